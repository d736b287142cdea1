#include "text_fields.hpp"

#include <charconv>
#include <sstream>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::dataset::detail {
namespace {

bool IsDigit(char c) { return c >= '0' && c <= '9'; }

}  // namespace

void LineError(const std::filesystem::path& file, int line, const std::string& reason) {
  core::ThrowInvalidInput(file.string() + ":" + std::to_string(line) + ": " + reason);
}

std::string Trim(std::string_view text) {
  const auto begin = text.find_first_not_of(" \t\r");
  if (begin == std::string_view::npos) return "";
  const auto end = text.find_last_not_of(" \t\r");
  return std::string(text.substr(begin, end - begin + 1));
}

std::vector<std::string> SplitCsv(const std::string& line) {
  std::vector<std::string> fields;
  std::string field;
  std::istringstream in(line);
  while (std::getline(in, field, ',')) fields.push_back(Trim(field));
  if (!line.empty() && line.back() == ',') fields.emplace_back();
  return fields;
}

bool ParseInt64(const std::string& text, std::int64_t* value) {
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, *value);
  return ec == std::errc() && ptr == end && !text.empty();
}

std::optional<double> ParseDouble(std::string_view text) {
  if (text.size() > 1 && text.front() == '+' && (IsDigit(text[1]) || text[1] == '.')) {
    text.remove_prefix(1);
  }
  double value = 0.0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size()) return std::nullopt;
  return value;
}

}  // namespace mosaicloc::dataset::detail
