#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace mosaicloc::runtime {

/// `mosaicloc bench registration`: mosaicloc's registration against its peers (OpenCV's ECC
/// and phase correlation, ViSP's template tracker alone) on the same 640x480 pairs, cut from
/// real textures with exact offsets, each method on one core.
struct RegistrationBenchOptions {
  std::vector<std::filesystem::path> textures;
  int pairs = 50;  ///< per texture
  std::uint64_t seed = 1;
  double max_shift_px = 8.0;      ///< largest offset along each axis
  double max_rotation_deg = 3.0;
  double noise_dn = 2.0;          ///< sensor noise standard deviation
  double max_gain_change = 0.15;  ///< the live image's gain, relative
  double max_offset_dn = 15.0;    ///< and offset
  double failure_px = 1.0;        ///< an error above this (at the image centre) is a failure
  double failure_deg = 0.1;
  /// Pairs whose live view is also from a camera up to this much higher or lower (relative:
  /// 0.03 is 3 %) and tilted by up to this much about each axis, degrees: the live image is
  /// then a pinhole's view of the floor (a homography of the reference), and the error is
  /// that of the image centre's floor point. Both 0: pairs related by a rotation and a shift.
  double max_scale_change = 0.0;
  double max_tilt_deg = 0.0;
  std::vector<std::string> methods;  ///< keys of RegistrationBenchMethods(); empty: all
  bool Check(std::string* why) const;
};

/// The methods' keys: ours, ours-9x128, ours-tiled, ours-visp, ours-tilt (twelve templates,
/// scale and tilt estimated), ours-observer (the pose by the founding paper's Kalman observer),
/// ecc, ecc-homography, phase, visp.
const std::vector<std::string>& RegistrationBenchMethods();

/// One method's figures over all pairs (NaN where nothing was measured).
struct RegistrationBenchRow {
  std::string method;  ///< its description
  std::size_t pairs = 0;
  double failure_rate = 0.0;
  double rms_px = 0.0, max_px = 0.0, rms_deg = 0.0, max_deg = 0.0;
  double mean_ms = 0.0, p50_ms = 0.0;
  double time_vs_ecc = 0.0;  ///< mean time over ECC's (NaN without ECC)
};

/// Runs the benchmark. Throws core::Error (invalid input) naming a texture that cannot be
/// read or is too small. `progress` (may be empty) gets the fraction of pairs done.
std::vector<RegistrationBenchRow> RunRegistrationBench(const RegistrationBenchOptions& options,
                                                       const std::function<void(double)>& progress = {});

/// `bench registration --json`: one object per method, null where nothing was measured.
nlohmann::json RegistrationBenchJson(const std::vector<RegistrationBenchRow>& rows);
/// The table `bench registration` prints: the pairs' settings, then a line per method.
std::string RegistrationBenchText(const RegistrationBenchOptions& options, const std::vector<RegistrationBenchRow>& rows);

}  // namespace mosaicloc::runtime
