// A dataset's encoder and frame lists (DatasetReader's streams), and its camera truth, behind a
// valid dataset.yaml: every line read as `replay` reads them.
#include "fuzz_input.hpp"
#include "mosaicloc/dataset/camera_truth.hpp"
#include "mosaicloc/dataset/dataset.hpp"

namespace {

const std::filesystem::path& Dataset() {
  static const std::filesystem::path dir = [] {
    const std::filesystem::path d = mosaicloc::fuzz::ScratchDir() / "dataset";
    std::filesystem::create_directories(d / "cam0" / "data");
    std::filesystem::create_directories(d / "encoders");
    std::filesystem::create_directories(d / "groundtruth");
    std::ofstream(d / "dataset.yaml")
        << "format_version: 1\ncamera:\n  width_px: 4\n  height_px: 4\n  mm_per_px: 0.25\n"
           "  vehicle_from_camera: {x_mm: 200, y_mm: 0, yaw_rad: 0}\nvehicle:\n  left_wheel_radius_mm: 75\n"
           "  right_wheel_radius_mm: 75\n  track_width_mm: 500\n  ticks_per_revolution: 4096\n";
    // A frame the list may name: 4 x 4 grey.
    static const unsigned char kPng[] = {
        0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44, 0x52, 0x00, 0x00,
        0x00, 0x04, 0x00, 0x00, 0x00, 0x04, 0x08, 0x00, 0x00, 0x00, 0x00, 0x8c, 0x9a, 0xc1, 0xa2, 0x00, 0x00, 0x00,
        0x0e, 0x49, 0x44, 0x41, 0x54, 0x78, 0x9c, 0x63, 0x68, 0x00, 0x02, 0x06, 0x54, 0x02, 0x00, 0x50, 0x14, 0x08,
        0x01, 0x70, 0x25, 0xae, 0x3f, 0x00, 0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82};
    mosaicloc::fuzz::WriteBytes(d / "cam0" / "data" / "1.png", kPng, sizeof(kPng));
    return d;
  }();
  return dir;
}

}  // namespace

// The first byte says which file the rest is.
extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::filesystem::path& dir = Dataset();
  const int which = data[0] % 3;
  const std::filesystem::path file = which == 0   ? dir / "encoders" / "data.csv"
                                     : which == 1 ? dir / "cam0" / "data.csv"
                                                  : dir / "groundtruth" / "camera.csv";
  // The other two lists: just their headers.
  std::ofstream(dir / "encoders" / "data.csv") << "#timestamp_ns,left_ticks,right_ticks\n";
  std::ofstream(dir / "cam0" / "data.csv") << "#timestamp_ns,filename\n";
  mosaicloc::fuzz::WriteBytes(file, data + 1, size - 1);
  mosaicloc::fuzz::ExpectOnlyCoreErrors([&] {
    if (which == 2) {
      mosaicloc::dataset::ReadCameraTruth(file);
      return;
    }
    const mosaicloc::dataset::DatasetReader reader(dir);
    auto encoders = reader.Encoders();
    while (encoders.Next()) {
    }
    auto frames = reader.Frames();
    while (frames.Next()) {
    }
  });
  return 0;
}
