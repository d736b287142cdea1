// A dataset's dataset.yaml (dataset::ReadDatasetInfo): camera, vehicle, provenance.
#include "fuzz_input.hpp"
#include "mosaicloc/dataset/dataset.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::filesystem::path file = mosaicloc::fuzz::ScratchDir() / "dataset.yaml";
  mosaicloc::fuzz::WriteBytes(file, data, size);
  mosaicloc::fuzz::ExpectOnlyCoreErrors([&] { mosaicloc::dataset::ReadDatasetInfo(file); });
  return 0;
}
