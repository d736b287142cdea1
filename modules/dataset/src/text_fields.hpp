#pragma once

// Parsing the fields of the dataset module's text files (CSV and TUM), shared by their
// readers so that every file reports bad input alike: "file:line: reason".

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace mosaicloc::dataset::detail {

/// Throws core::Error (invalid input) "file:line: reason".
[[noreturn]] void LineError(const std::filesystem::path& file, int line, const std::string& reason);

/// `text` without leading and trailing spaces, tabs and carriage returns.
std::string Trim(std::string_view text);

/// The comma-separated fields of a line, each trimmed; a trailing comma gives an empty last field.
std::vector<std::string> SplitCsv(const std::string& line);

/// A whole decimal integer, or false.
bool ParseInt64(const std::string& text, std::int64_t* value);

/// A whole decimal number (a leading '+' allowed), or nothing.
std::optional<double> ParseDouble(std::string_view text);

}  // namespace mosaicloc::dataset::detail
