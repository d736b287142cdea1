#pragma once

#include <filesystem>
#include <string>

#include <yaml-cpp/yaml.h>

#include "mosaicloc/runtime/settings.hpp"

namespace mosaicloc::runtime {

/// Everything `replay` and `run` read from the localizer configuration: see
/// config/default/localizer.yaml for every key, its unit and default.
using LocalizerConfig = LocalizationSettings;

/// Reads a localizer configuration. Keys left out keep their defaults; unknown keys, wrong
/// types and values out of range are all reported at once as core::Error naming file, line
/// and key.
LocalizerConfig LoadLocalizerConfig(const std::filesystem::path& file);
void ReadLocalizerConfig(const YAML::Node& node, const std::string& file_name, LocalizerConfig* config);

}  // namespace mosaicloc::runtime
