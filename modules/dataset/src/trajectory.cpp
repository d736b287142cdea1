#include "mosaicloc/dataset/trajectory.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <system_error>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/file.hpp"
#include "text_fields.hpp"

namespace mosaicloc::dataset {


namespace {

constexpr std::int64_t kNanosecondsPerSecond = 1'000'000'000;
constexpr int kFieldCount = 8;
constexpr std::array<const char*, kFieldCount> kFieldNames = {"timestamp_s", "x_m", "y_m", "z_m",
                                                              "qx",          "qy",  "qz",  "qw"};

using detail::ParseDouble;

bool IsDigit(char c) { return c >= '0' && c <= '9'; }

std::vector<std::string_view> SplitFields(std::string_view line) {
  std::vector<std::string_view> fields;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    const std::size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
    if (i > start) fields.push_back(line.substr(start, i - start));
  }
  return fields;
}

std::string FormatFixed(double value, int decimals) {
  std::array<char, 64> buffer{};
  const auto [end, ec] = std::to_chars(buffer.data(), buffer.data() + buffer.size(), value,
                                       std::chars_format::fixed, decimals);
  if (ec != std::errc()) return std::to_string(value);
  return std::string(buffer.data(), end);
}

std::string FormatShort(double value) {
  std::ostringstream out;
  out.precision(6);
  out << value;
  return out.str();
}

}  // namespace

std::string FormatSeconds(core::Timestamp time) {
  const std::int64_t ns = time.nanoseconds();
  const std::uint64_t magnitude =
      ns < 0 ? 0 - static_cast<std::uint64_t>(ns) : static_cast<std::uint64_t>(ns);
  std::string fraction = std::to_string(magnitude % kNanosecondsPerSecond);
  fraction.insert(0, 9 - fraction.size(), '0');
  return (ns < 0 ? "-" : "") + std::to_string(magnitude / kNanosecondsPerSecond) + "." + fraction;
}

// value = sign * digits * 10^(exponent - fraction_digits) seconds
//       = sign * digits * 10^(exponent - fraction_digits + 9) nanoseconds,
// evaluated on the digit string so that any representable nanosecond count is exact.
std::optional<core::Timestamp> ParseSeconds(std::string_view text) {
  std::size_t i = 0;
  bool negative = false;
  if (i < text.size() && (text[i] == '+' || text[i] == '-')) negative = text[i++] == '-';
  std::string digits;
  int fraction_digits = 0;
  while (i < text.size() && IsDigit(text[i])) digits += text[i++];
  if (i < text.size() && text[i] == '.') {
    ++i;
    while (i < text.size() && IsDigit(text[i])) {
      digits += text[i++];
      ++fraction_digits;
    }
  }
  if (digits.empty()) return std::nullopt;
  long exponent = 0;
  if (i < text.size() && (text[i] == 'e' || text[i] == 'E')) {
    ++i;
    bool exponent_negative = false;
    if (i < text.size() && (text[i] == '+' || text[i] == '-')) exponent_negative = text[i++] == '-';
    if (i == text.size() || !IsDigit(text[i])) return std::nullopt;
    while (i < text.size() && IsDigit(text[i])) {
      exponent = std::min(exponent * 10 + (text[i++] - '0'), 100'000L);
    }
    if (exponent_negative) exponent = -exponent;
  }
  if (i != text.size()) return std::nullopt;

  const std::size_t first_nonzero = digits.find_first_not_of('0');
  if (first_nonzero == std::string::npos) return core::Timestamp::FromNanoseconds(0);
  digits.erase(0, first_nonzero);

  constexpr std::uint64_t kMax =
      static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max());
  const auto append_digit = [](std::uint64_t* value, int digit) {
    if (*value > (kMax - static_cast<std::uint64_t>(digit)) / 10) return false;
    *value = *value * 10 + static_cast<std::uint64_t>(digit);
    return true;
  };
  const long shift = exponent - fraction_digits + 9;
  const long digit_count = static_cast<long>(digits.size());
  const long kept = shift >= 0 ? digit_count : digit_count + shift;
  if (kept > 19) return std::nullopt;
  std::uint64_t value = 0;
  for (long k = 0; k < kept; ++k) {
    if (!append_digit(&value, digits[static_cast<std::size_t>(k)] - '0')) return std::nullopt;
  }
  if (shift > 0) {
    for (long k = 0; k < shift; ++k) {
      if (!append_digit(&value, 0)) return std::nullopt;
    }
  } else if (kept >= 0 && kept < digit_count && digits[static_cast<std::size_t>(kept)] >= '5') {
    if (value == kMax) return std::nullopt;
    ++value;
  }
  const auto ns = static_cast<std::int64_t>(value);
  return core::Timestamp::FromNanoseconds(negative ? -ns : ns);
}

Trajectory ReadTum(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    core::ThrowInvalidInput(file.string() +
                            ": cannot open TUM trajectory: " + std::strerror(errno));
  }
  Trajectory trajectory;
  std::string line;
  std::int64_t line_number = 0;
  std::int64_t previous_line = 0;
  while (std::getline(in, line)) {
    ++line_number;
    const auto where = [&] { return file.string() + ":" + std::to_string(line_number) + ": "; };
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const std::vector<std::string_view> fields = SplitFields(line);
    if (fields.empty() || fields.front().front() == '#') continue;
    if (fields.size() != kFieldCount) {
      core::ThrowInvalidInput(where() +
                              "expected 8 fields (timestamp_s x_m y_m z_m qx qy qz qw), found " +
                              std::to_string(fields.size()));
    }
    const std::optional<core::Timestamp> time = ParseSeconds(fields[0]);
    if (!time) {
      core::ThrowInvalidInput(where() + "field 1 (timestamp_s) '" + std::string(fields[0]) +
                              "' is not a number of seconds in the int64 nanosecond range");
    }
    std::array<double, kFieldCount> values{};
    for (int k = 1; k < kFieldCount; ++k) {
      const std::optional<double> value = ParseDouble(fields[static_cast<std::size_t>(k)]);
      const std::string field_name = "field " + std::to_string(k + 1) + " (" +
                                     kFieldNames[static_cast<std::size_t>(k)] + ") '" +
                                     std::string(fields[static_cast<std::size_t>(k)]) + "'";
      if (!value) core::ThrowInvalidInput(where() + field_name + " is not a number");
      if (!std::isfinite(*value)) core::ThrowInvalidInput(where() + field_name + " is not finite");
      values[static_cast<std::size_t>(k)] = *value;
    }
    double qx = values[4];
    double qy = values[5];
    double qz = values[6];
    double qw = values[7];
    const double norm = std::sqrt(qx * qx + qy * qy + qz * qz + qw * qw);
    if (std::abs(norm - 1.0) > kTumQuaternionNormTolerance) {
      core::ThrowInvalidInput(where() + "quaternion (qx qy qz qw) has norm " + FormatShort(norm) +
                              ", not 1 (tolerance " + FormatShort(kTumQuaternionNormTolerance) +
                              ")");
    }
    qx /= norm;
    qy /= norm;
    qz /= norm;
    qw /= norm;
    // The tilt of the rotation's z axis away from world z is 2 asin(sqrt(qx^2 + qy^2)).
    const double tilt_rad = 2.0 * std::asin(std::min(1.0, std::sqrt(qx * qx + qy * qy)));
    if (tilt_rad > kTumMaxTiltRad) {
      core::ThrowInvalidInput(where() + "rotation is not about z: qx = " + FormatShort(qx) +
                              ", qy = " + FormatShort(qy) + " tilt it by " + FormatShort(tilt_rad) +
                              " rad (at most " + FormatShort(kTumMaxTiltRad) +
                              "); a planar trajectory needs qx = qy = 0");
    }
    if (!trajectory.empty() && *time <= trajectory.back().time) {
      core::ThrowInvalidInput(
          where() + "timestamp " + FormatSeconds(*time) + " s is not after the previous pose's " +
          FormatSeconds(trajectory.back().time) + " s (line " + std::to_string(previous_line) +
          "); timestamps must strictly increase");
    }
    trajectory.push_back(
        {*time, core::Pose2(values[1] * 1000.0, values[2] * 1000.0, 2.0 * std::atan2(qz, qw))});
    previous_line = line_number;
  }
  if (in.bad()) {
    core::ThrowInvalidInput(file.string() + ": read error after line " +
                            std::to_string(line_number));
  }
  if (trajectory.empty()) {
    core::ThrowInvalidInput(file.string() +
                            ": no pose in the TUM trajectory (empty, or only comments)");
  }
  return trajectory;
}

void WriteTum(const std::filesystem::path& file, const Trajectory& trajectory) {
  std::string text = "# timestamp_s x_m y_m z_m qx qy qz qw\n";
  text.reserve(text.size() + trajectory.size() * 96);
  for (std::size_t i = 0; i < trajectory.size(); ++i) {
    const StampedPose& pose = trajectory[i];
    if (i > 0 && pose.time <= trajectory[i - 1].time) {
      core::ThrowInvalidInput(file.string() +
                              ": cannot write a trajectory whose time does not "
                              "strictly increase (pose " +
                              std::to_string(i) + " at " + FormatSeconds(pose.time) +
                              " s follows " + FormatSeconds(trajectory[i - 1].time) + " s)");
    }
    const double half_yaw = 0.5 * pose.world_from_vehicle.yaw_rad();
    text += FormatSeconds(pose.time);
    text += ' ';
    text += FormatFixed(pose.world_from_vehicle.x_mm() / 1000.0, 9);
    text += ' ';
    text += FormatFixed(pose.world_from_vehicle.y_mm() / 1000.0, 9);
    text += " 0 0 0 ";
    text += FormatFixed(std::sin(half_yaw), 12);
    text += ' ';
    text += FormatFixed(std::cos(half_yaw), 12);
    text += '\n';
  }
  core::WriteFileAtomically(file, text);
}

std::optional<core::Pose2> PoseAt(const Trajectory& trajectory, core::Timestamp t,
                                  core::Duration max_gap) {
  if (trajectory.empty() || t < trajectory.front().time || t > trajectory.back().time) {
    return std::nullopt;
  }
  const auto after = std::lower_bound(
      trajectory.begin(), trajectory.end(), t,
      [](const StampedPose& pose, core::Timestamp time) { return pose.time < time; });
  if (after->time == t) return after->world_from_vehicle;
  const auto before = std::prev(after);
  const core::Duration gap = after->time - before->time;
  if (gap > max_gap) return std::nullopt;
  const double fraction =
      static_cast<double>((t - before->time).count()) / static_cast<double>(gap.count());
  return core::Interpolate(before->world_from_vehicle, after->world_from_vehicle, fraction);
}

}  // namespace mosaicloc::dataset
