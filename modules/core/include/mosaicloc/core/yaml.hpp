#pragma once

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <initializer_list>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include <yaml-cpp/yaml.h>

namespace mosaicloc::core {

/// Collects every problem found while reading a configuration, so a user sees all of them
/// at once instead of fixing one per run.
class YamlProblems {
 public:
  /// Adds a problem; the same problem found twice (by two checks) is kept once.
  void Add(std::string message) {
    if (std::find(messages_.begin(), messages_.end(), message) == messages_.end()) {
      messages_.push_back(std::move(message));
    }
  }
  bool empty() const { return messages_.empty(); }
  const std::vector<std::string>& messages() const { return messages_; }
  /// Throws core::Error (invalid input) listing every problem, one per line.
  void ThrowIfAny() const;

 private:
  std::vector<std::string> messages_;
};

/// A check on a value read from YAML: returns the reason it is not acceptable, or nothing.
template <typename T>
using YamlCheck = std::function<std::optional<std::string>(const T&)>;

/// Common checks. Their messages state the accepted range.
YamlCheck<double> Positive();
YamlCheck<double> NonNegative();
YamlCheck<double> InRange(double min_inclusive, double max_inclusive);
YamlCheck<std::int64_t> PositiveInteger();
YamlCheck<std::int64_t> IntegerInRange(std::int64_t min_inclusive, std::int64_t max_inclusive);
YamlCheck<std::string> OneOf(std::vector<std::string> choices);

/// One YAML mapping being read into an options struct. It records which keys were read;
/// Finish() reports every key that was not (a typo must not silently fall back to a default).
/// Problems (missing keys, wrong types, values out of range, unknown keys) are added to the
/// shared YamlProblems with "file:line: path.key: reason".
///
///   YamlProblems problems;
///   YamlMap camera = YamlMap::Root(node, "site.yaml", &problems).RequiredMap("camera");
///   camera.Required("width_px", &options.width_px, PositiveInteger());
///   camera.Optional("mm_per_px", &options.mm_per_px, Positive());
///   camera.Finish();
///   problems.ThrowIfAny();
class YamlMap {
 public:
  /// The document root; a root that is not a mapping is reported as a problem.
  static YamlMap Root(const YAML::Node& node, std::string file, YamlProblems* problems);

  /// Reads key into *value; a missing key is a problem.
  void Required(std::string_view key, double* value, YamlCheck<double> check = {});
  void Required(std::string_view key, std::int64_t* value, YamlCheck<std::int64_t> check = {});
  void Required(std::string_view key, int* value, YamlCheck<std::int64_t> check = {});
  void Required(std::string_view key, bool* value);
  void Required(std::string_view key, std::string* value, YamlCheck<std::string> check = {});
  /// Reads key into *value if present; otherwise *value keeps its default.
  void Optional(std::string_view key, double* value, YamlCheck<double> check = {});
  void Optional(std::string_view key, std::int64_t* value, YamlCheck<std::int64_t> check = {});
  void Optional(std::string_view key, int* value, YamlCheck<std::int64_t> check = {});
  void Optional(std::string_view key, bool* value);
  void Optional(std::string_view key, std::string* value, YamlCheck<std::string> check = {});

  /// Reads an enumeration by the names ToString gives its values (`all` lists them).
  template <typename Enum, std::size_t N>
  void OptionalEnum(std::string_view key, Enum* value, const Enum (&all)[N]) {
    std::string name = ToString(*value);
    std::vector<std::string> names;
    for (const Enum e : all) names.emplace_back(ToString(e));
    Optional(key, &name, OneOf(names));
    for (const Enum e : all) {
      if (name == ToString(e)) *value = e;
    }
  }

  /// A nested mapping. A missing required map is a problem and yields an empty map whose
  /// reads are all skipped (only the map itself is reported missing).
  YamlMap RequiredMap(std::string_view key);
  YamlMap OptionalMap(std::string_view key);
  bool Has(std::string_view key) const;

  /// Reports keys present in the mapping but never read.
  void Finish();

  /// Where this mapping is, for messages: "file:line: path".
  std::string Where() const;
  /// Adds a problem about `key` of this mapping (e.g. a cross-field check).
  void AddProblem(std::string_view key, const std::string& reason);
  /// Runs the Check() of the options this mapping was read into and makes its complaint a
  /// problem of this mapping: the valid ranges are stated once, in Check(), not again by
  /// each reader. A complaint that begins with one of this mapping's keys is reported at
  /// that key's line. Nothing is checked for an absent optional mapping (the defaults stand).
  template <typename Options>
  void Check(const Options& options) {
    std::string why;
    if (!absent_ && !options.Check(&why)) AddCheckProblem(why, {}, /*only_own_keys=*/false);
  }
  /// The same for options whose fields this mapping holds only some of: a complaint is
  /// reported only when it begins with one of this mapping's keys, or with a field that
  /// `yaml_key_of` names one of them ({field, key} pairs, for fields the file calls otherwise).
  /// Returns whether it was.
  template <typename Options>
  bool CheckOwnKeys(const Options& options, std::initializer_list<std::pair<std::string_view, std::string_view>>
                                                yaml_key_of = {}) {
    std::string why;
    return !absent_ && !options.Check(&why) && AddCheckProblem(why, yaml_key_of, /*only_own_keys=*/true);
  }

 private:
  YamlMap(YAML::Node node, std::string file, std::string path, YamlProblems* problems, bool absent);
  std::optional<YAML::Node> Lookup(std::string_view key, bool required);
  std::string Location(const YAML::Node& node, std::string_view key) const;
  bool AddCheckProblem(const std::string& why,
                       std::initializer_list<std::pair<std::string_view, std::string_view>> yaml_key_of,
                       bool only_own_keys);
  template <typename T>
  void ReadNumber(std::string_view key, T* value, const YamlCheck<T>& check, bool required);

  YAML::Node node_;
  YAML::Mark key_mark_ = YAML::Mark::null_mark();  // where this mapping's own key is
  std::string file_;
  std::string path_;
  YamlProblems* problems_;
  bool absent_ = false;
  std::set<std::string, std::less<>> read_keys_;
};

/// Loads and parses a YAML file; throws core::Error naming the file (and the line of a
/// syntax error) when it cannot.
YAML::Node LoadYamlFile(const std::filesystem::path& file);

}  // namespace mosaicloc::core
