// fixes.csv as a replay report or a live recording holds it (dataset::ReadFixesCsv).
#include "fuzz_input.hpp"
#include "mosaicloc/dataset/fixes.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::filesystem::path file = mosaicloc::fuzz::ScratchDir() / "fixes.csv";
  mosaicloc::fuzz::WriteBytes(file, data, size);
  mosaicloc::fuzz::ExpectOnlyCoreErrors([&] { mosaicloc::dataset::ReadFixesCsv(file); });
  return 0;
}
