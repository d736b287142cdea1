#include "mosaicloc/core/yaml.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <sstream>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::core {
namespace {

std::string FormatNumber(double value) {
  std::ostringstream out;
  out << value;
  return out.str();
}

// Levenshtein distance, for "did you mean" on unknown keys.
std::size_t EditDistance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t substitution = diagonal + (a[i - 1] == b[j - 1] ? 0 : 1);
      diagonal = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, substitution});
    }
  }
  return row[b.size()];
}

bool ParseScalar(const std::string& text, double* value) {
  const char* begin = text.data();
  const char* end = begin + text.size();
  const auto [ptr, ec] = std::from_chars(begin, end, *value);
  return ec == std::errc() && ptr == end && std::isfinite(*value);
}

bool ParseScalar(const std::string& text, std::int64_t* value) {
  const char* begin = text.data();
  const char* end = begin + text.size();
  if (begin != end && *begin == '+') ++begin;
  const auto [ptr, ec] = std::from_chars(begin, end, *value);
  return ec == std::errc() && ptr == end;
}

const char* TypeName(const double*) { return "a number"; }
const char* TypeName(const std::int64_t*) { return "an integer"; }

}  // namespace

void YamlProblems::ThrowIfAny() const {
  if (messages_.empty()) return;
  std::string text = messages_.size() == 1 ? "configuration problem:\n"
                                           : std::to_string(messages_.size()) + " configuration problems:\n";
  for (const auto& message : messages_) text += "  " + message + "\n";
  text.pop_back();
  ThrowInvalidInput(text);
}

YamlCheck<double> Positive() {
  return [](const double& v) -> std::optional<std::string> {
    if (v > 0.0) return std::nullopt;
    return "must be > 0, got " + FormatNumber(v);
  };
}

YamlCheck<double> NonNegative() {
  return [](const double& v) -> std::optional<std::string> {
    if (v >= 0.0) return std::nullopt;
    return "must be >= 0, got " + FormatNumber(v);
  };
}

YamlCheck<double> InRange(double min_inclusive, double max_inclusive) {
  return [=](const double& v) -> std::optional<std::string> {
    if (v >= min_inclusive && v <= max_inclusive) return std::nullopt;
    return "must be in [" + FormatNumber(min_inclusive) + ", " + FormatNumber(max_inclusive) +
           "], got " + FormatNumber(v);
  };
}

YamlCheck<std::int64_t> PositiveInteger() {
  return [](const std::int64_t& v) -> std::optional<std::string> {
    if (v > 0) return std::nullopt;
    return "must be > 0, got " + std::to_string(v);
  };
}

YamlCheck<std::int64_t> IntegerInRange(std::int64_t min_inclusive, std::int64_t max_inclusive) {
  return [=](const std::int64_t& v) -> std::optional<std::string> {
    if (v >= min_inclusive && v <= max_inclusive) return std::nullopt;
    return "must be in [" + std::to_string(min_inclusive) + ", " + std::to_string(max_inclusive) +
           "], got " + std::to_string(v);
  };
}

YamlCheck<std::string> OneOf(std::vector<std::string> choices) {
  return [choices = std::move(choices)](const std::string& v) -> std::optional<std::string> {
    if (std::find(choices.begin(), choices.end(), v) != choices.end()) return std::nullopt;
    std::string list;
    for (const auto& choice : choices) list += (list.empty() ? "" : ", ") + choice;
    return "must be one of " + list + ", got '" + v + "'";
  };
}

YamlMap::YamlMap(YAML::Node node, std::string file, std::string path, YamlProblems* problems,
                 bool absent)
    : node_(std::move(node)), file_(std::move(file)), path_(std::move(path)), problems_(problems),
      absent_(absent) {}

YamlMap YamlMap::Root(const YAML::Node& node, std::string file, YamlProblems* problems) {
  YamlMap root(node, std::move(file), "", problems, false);
  if (!node.IsMap()) {
    problems->Add(root.Location(node, "") + "the document must be a mapping of keys to values");
    root.absent_ = true;
  }
  return root;
}

std::string YamlMap::Location(const YAML::Node& node, std::string_view key) const {
  std::string where = file_;
  // A block mapping is marked at its first entry; a key missing from it is better reported
  // at the line naming the mapping itself.
  const YAML::Mark mark = (&node == &node_ && key_mark_.line >= 0) ? key_mark_ : node.Mark();
  if (mark.line >= 0) where += ":" + std::to_string(mark.line + 1);
  where += ": ";
  std::string name = path_;
  if (!key.empty()) name += (name.empty() ? "" : ".") + std::string(key);
  if (!name.empty()) where += name + ": ";
  return where;
}

std::string YamlMap::Where() const {
  std::string where = Location(node_, "");
  // drop the trailing ": "
  return where.substr(0, where.size() - 2);
}

void YamlMap::AddProblem(std::string_view key, const std::string& reason) {
  if (!key.empty() && !absent_ && node_.IsMap()) {
    const YAML::Node child = node_[std::string(key)];
    if (child.IsDefined()) {
      problems_->Add(Location(child, key) + reason);
      return;
    }
  }
  // A problem of the mapping as a whole, or of a key it lacks: at the line naming the mapping.
  problems_->Add(Location(node_, key) + reason);
}

bool YamlMap::AddCheckProblem(const std::string& why,
                               std::initializer_list<std::pair<std::string_view, std::string_view>> yaml_key_of,
                               bool only_own_keys) {
  std::size_t end = 0;
  while (end < why.size() && (std::islower(static_cast<unsigned char>(why[end])) ||
                              std::isdigit(static_cast<unsigned char>(why[end])) || why[end] == '_')) {
    ++end;
  }
  std::string key = why.substr(0, end);
  for (const auto& [field, yaml_key] : yaml_key_of) {
    if (key == field) key = yaml_key;
  }
  if (end > 0 && end < why.size() && why[end] == ' ' && Has(key)) {
    AddProblem(key, why.substr(end + 1));
    return true;
  }
  if (only_own_keys) return false;
  AddProblem("", why);
  return true;
}

bool YamlMap::Has(std::string_view key) const {
  return !absent_ && node_.IsMap() && node_[std::string(key)].IsDefined();
}

std::optional<YAML::Node> YamlMap::Lookup(std::string_view key, bool required) {
  if (absent_) return std::nullopt;
  read_keys_.emplace(key);
  YAML::Node child = node_[std::string(key)];
  if (!child.IsDefined()) {
    if (required) problems_->Add(Location(node_, key) + "missing required key");
    return std::nullopt;
  }
  if (child.IsNull()) {
    problems_->Add(Location(child, key) + "has no value");
    return std::nullopt;
  }
  return child;
}

template <typename T>
void YamlMap::ReadNumber(std::string_view key, T* value, const YamlCheck<T>& check, bool required) {
  const auto child = Lookup(key, required);
  if (!child) return;
  T parsed{};
  if (!child->IsScalar() || !ParseScalar(child->Scalar(), &parsed)) {
    problems_->Add(Location(*child, key) + "expected " + TypeName(value) + ", got '" +
                   (child->IsScalar() ? child->Scalar() : std::string("a nested value")) + "'");
    return;
  }
  if (check) {
    if (const auto reason = check(parsed)) {
      problems_->Add(Location(*child, key) + *reason);
      return;
    }
  }
  *value = parsed;
}

void YamlMap::Required(std::string_view key, double* value, YamlCheck<double> check) {
  ReadNumber(key, value, check, true);
}
void YamlMap::Optional(std::string_view key, double* value, YamlCheck<double> check) {
  ReadNumber(key, value, check, false);
}
void YamlMap::Required(std::string_view key, std::int64_t* value, YamlCheck<std::int64_t> check) {
  ReadNumber(key, value, check, true);
}
void YamlMap::Optional(std::string_view key, std::int64_t* value, YamlCheck<std::int64_t> check) {
  ReadNumber(key, value, check, false);
}

void YamlMap::Required(std::string_view key, int* value, YamlCheck<std::int64_t> check) {
  std::int64_t wide = *value;
  const auto in_int = [check](const std::int64_t& v) -> std::optional<std::string> {
    if (v < INT32_MIN || v > INT32_MAX) return "does not fit a 32-bit integer: " + std::to_string(v);
    return check ? check(v) : std::nullopt;
  };
  ReadNumber<std::int64_t>(key, &wide, in_int, true);
  *value = static_cast<int>(wide);
}
void YamlMap::Optional(std::string_view key, int* value, YamlCheck<std::int64_t> check) {
  std::int64_t wide = *value;
  const auto in_int = [check](const std::int64_t& v) -> std::optional<std::string> {
    if (v < INT32_MIN || v > INT32_MAX) return "does not fit a 32-bit integer: " + std::to_string(v);
    return check ? check(v) : std::nullopt;
  };
  ReadNumber<std::int64_t>(key, &wide, in_int, false);
  *value = static_cast<int>(wide);
}

namespace {
bool ReadBool(const YAML::Node& node, bool* value) {
  if (!node.IsScalar()) return false;
  const std::string& text = node.Scalar();
  if (text == "true" || text == "True" || text == "yes") { *value = true; return true; }
  if (text == "false" || text == "False" || text == "no") { *value = false; return true; }
  return false;
}
}  // namespace

void YamlMap::Required(std::string_view key, bool* value) {
  if (const auto child = Lookup(key, true); child && !ReadBool(*child, value)) {
    problems_->Add(Location(*child, key) + "expected true or false");
  }
}
void YamlMap::Optional(std::string_view key, bool* value) {
  if (const auto child = Lookup(key, false); child && !ReadBool(*child, value)) {
    problems_->Add(Location(*child, key) + "expected true or false");
  }
}

void YamlMap::Required(std::string_view key, std::string* value, YamlCheck<std::string> check) {
  Optional(key, value, std::move(check));
  if (!absent_ && !Has(key)) problems_->Add(Location(node_, key) + "missing required key");
}
void YamlMap::Optional(std::string_view key, std::string* value, YamlCheck<std::string> check) {
  const auto child = Lookup(key, false);
  if (!child) return;
  if (!child->IsScalar()) {
    problems_->Add(Location(*child, key) + "expected a text value");
    return;
  }
  if (check) {
    if (const auto reason = check(child->Scalar())) {
      problems_->Add(Location(*child, key) + *reason);
      return;
    }
  }
  *value = child->Scalar();
}

namespace {
YAML::Mark KeyMark(const YAML::Node& map, std::string_view key) {
  if (!map.IsMap()) return YAML::Mark::null_mark();
  for (const auto& entry : map) {
    if (entry.first.IsScalar() && entry.first.Scalar() == key) return entry.first.Mark();
  }
  return YAML::Mark::null_mark();
}
}  // namespace

YamlMap YamlMap::RequiredMap(std::string_view key) {
  const std::string path = path_.empty() ? std::string(key) : path_ + "." + std::string(key);
  const auto child = Lookup(key, true);
  if (child && !child->IsMap()) {
    problems_->Add(Location(*child, key) + "expected a mapping of keys to values");
    return YamlMap(*child, file_, path, problems_, true);
  }
  YamlMap map(child.value_or(YAML::Node()), file_, path, problems_, !child);
  if (child) map.key_mark_ = KeyMark(node_, key);
  return map;
}

YamlMap YamlMap::OptionalMap(std::string_view key) {
  const std::string path = path_.empty() ? std::string(key) : path_ + "." + std::string(key);
  const auto child = Lookup(key, false);
  if (child && !child->IsMap()) {
    problems_->Add(Location(*child, key) + "expected a mapping of keys to values");
    return YamlMap(*child, file_, path, problems_, true);
  }
  YamlMap map(child.value_or(YAML::Node()), file_, path, problems_, !child);
  if (child) map.key_mark_ = KeyMark(node_, key);
  return map;
}

void YamlMap::Finish() {
  if (absent_ || !node_.IsMap()) return;
  for (const auto& entry : node_) {
    // A key that is itself a mapping or a list (YAML's "? " form) names nothing here.
    if (!entry.first.IsScalar()) {
      problems_->Add(Location(entry.first, "?") + "a key must be a plain name, not a mapping or a list");
      continue;
    }
    const std::string key = entry.first.Scalar();
    if (read_keys_.count(key) != 0) continue;
    std::string message = "unknown key";
    std::size_t best_distance = 3;
    for (const auto& known : read_keys_) {
      const std::size_t distance = EditDistance(key, known);
      if (distance < best_distance) {
        best_distance = distance;
        message = "unknown key (did you mean '" + known + "'?)";
      }
    }
    problems_->Add(Location(entry.first, key) + message);
  }
}

YAML::Node LoadYamlFile(const std::filesystem::path& file) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) {
    ThrowInvalidInput(file.string() + ": no such configuration file");
  }
  try {
    return YAML::LoadFile(file.string());
  } catch (const YAML::ParserException& e) {
    ThrowInvalidInput(file.string() + ":" + std::to_string(e.mark.line + 1) + ": YAML syntax error: " + e.msg);
  } catch (const YAML::BadFile&) {
    ThrowInvalidInput(file.string() + ": cannot be read");
  }
}

}  // namespace mosaicloc::core
