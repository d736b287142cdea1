// A TUM trajectory (dataset::ReadTum): ground truth, estimates, `map build --poses TUM`.
#include "fuzz_input.hpp"
#include "mosaicloc/dataset/trajectory.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::filesystem::path file = mosaicloc::fuzz::ScratchDir() / "data.tum";
  mosaicloc::fuzz::WriteBytes(file, data, size);
  mosaicloc::fuzz::ExpectOnlyCoreErrors([&] { mosaicloc::dataset::ReadTum(file); });
  return 0;
}
