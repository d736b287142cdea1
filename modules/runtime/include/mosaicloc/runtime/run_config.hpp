#pragma once

#include <filesystem>
#include <string>

#include <yaml-cpp/yaml.h>

#include "mosaicloc/runtime/localization_config.hpp"
#include "mosaicloc/io/plc_link.hpp"
#include "mosaicloc/runtime/live_run.hpp"

namespace mosaicloc::runtime {

/// What `mosaicloc run` reads from --config: see config/default/run.yaml for every key,
/// its unit and default.
using RunConfig = LiveRunOptions;

/// Reads a run configuration. Keys left out keep their defaults; every problem (unknown key,
/// wrong type, value out of range, inconsistent register map) is reported at once as a
/// core::Error naming file, line and key.
RunConfig LoadRunConfig(const std::filesystem::path& file);

/// The register map section of a run configuration (also what plc-sim takes).
void ReadRegisterMap(const YAML::Node& node, const std::string& file_name, io::RegisterMap* map);

}  // namespace mosaicloc::runtime
