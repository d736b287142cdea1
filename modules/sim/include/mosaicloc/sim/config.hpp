#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

#include <yaml-cpp/yaml.h>

#include "mosaicloc/sim/simulator.hpp"

namespace mosaicloc::sim {

/// Reads a simulator configuration (see config/default/simulator.yaml: every key, its unit
/// and default). Keys left out keep their defaults; unknown keys, wrong types and values
/// out of range are all reported at once as core::Error naming file, line and key.
SimulatorOptions LoadSimulatorConfig(const std::filesystem::path& file);
/// The same, or the defaults for an empty path.
SimulatorOptions SimulatorConfigOrDefaults(const std::filesystem::path& file);

/// What a command line changes of a simulator configuration (`simulate`, `bench soak`); a
/// field left unset keeps the configuration's value.
struct SimulatorOverrides {
  std::string floor;  ///< 'procedural' or an image file (FloorChoice::Named: unevenness and texel size kept)
  std::optional<std::uint64_t> floor_seed;
  std::optional<double> floor_mm_per_texel;
  std::string route;
  std::optional<std::int64_t> frames;  ///< a frame count replaces the configuration's laps
  std::optional<int> laps;
  std::optional<double> speed_mps;
  std::optional<std::uint64_t> seed;
  std::optional<int> threads;
};
/// The configuration in `file` (the defaults for an empty path) with `overrides` applied.
/// Throws core::Error naming file, line and key for a configuration that cannot be read.
SimulatorOptions SimulatorOptionsFor(const std::filesystem::path& file, const SimulatorOverrides& overrides);

/// Applies a configuration document to options (the part of LoadSimulatorConfig that does
/// not touch the file system), for tests.
void ReadSimulatorConfig(const YAML::Node& node, const std::string& file_name, SimulatorOptions* options);

}  // namespace mosaicloc::sim
