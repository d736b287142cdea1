#pragma once

#include <filesystem>
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

/// Applies a configuration document to options (the part of LoadSimulatorConfig that does
/// not touch the file system), for tests.
void ReadSimulatorConfig(const YAML::Node& node, const std::string& file_name, SimulatorOptions* options);

}  // namespace mosaicloc::sim
