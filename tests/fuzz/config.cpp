// The configuration loaders: `run --config` (LoadRunConfig, with its register map),
// `replay --config` (LoadLocalizerConfig) and `simulate --config` (LoadSimulatorConfig). The
// input's first byte picks the loader ('r', 'l', anything else the simulator's), the rest is
// the YAML file.
#include "fuzz_input.hpp"
#include "mosaicloc/runtime/localization_config.hpp"
#include "mosaicloc/runtime/run_config.hpp"
#include "mosaicloc/sim/config.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::filesystem::path file = mosaicloc::fuzz::ScratchDir() / "config.yaml";
  mosaicloc::fuzz::WriteBytes(file, data + 1, size - 1);
  mosaicloc::fuzz::ExpectOnlyCoreErrors([&] {
    switch (data[0]) {
      case 'r': mosaicloc::runtime::LoadRunConfig(file); break;
      case 'l': mosaicloc::runtime::LoadLocalizerConfig(file); break;
      default: mosaicloc::sim::LoadSimulatorConfig(file); break;
    }
  });
  return 0;
}
