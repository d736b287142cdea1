#include "mosaicloc/calibration/ground.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/dataset/dataset.hpp"

namespace mosaicloc::calibration {

std::int64_t RectifyDataset(const std::filesystem::path& raw, const Rectifier& rectifier, const std::string& note,
                            const std::optional<core::Pose2>& vehicle_from_camera, const std::filesystem::path& out,
                            bool overwrite) {
  const dataset::DatasetReader reader(raw);
  const camera::IdealCameraOptions& ideal = rectifier.calibration().ideal;
  dataset::CameraInfo ideal_info = reader.info().camera;
  ideal_info.width_px = ideal.width_px;
  ideal_info.height_px = ideal.height_px;
  ideal_info.mm_per_px = ideal.mm_per_px;
  if (vehicle_from_camera) ideal_info.vehicle_from_camera = *vehicle_from_camera;
  dataset::DatasetWriter writer(out, dataset::DerivedInfo(reader, ideal_info, note), overwrite);
  std::int64_t count = 0;
  for (auto frames = reader.Frames(); auto frame = frames.Next();) {
    cv::Mat rectified;
    if (!rectifier.Rectify(frame->image, &rectified)) {
      core::ThrowInvalidInput(frame->path.string() + ": not the calibrated raw size " +
                              std::to_string(rectifier.calibration().intrinsics.width_px) + "x" +
                              std::to_string(rectifier.calibration().intrinsics.height_px));
    }
    writer.AddFrame(frame->time, rectified);
    ++count;
  }
  dataset::CopyEncodersAndTruth(reader, &writer);
  writer.Commit();
  return count;
}

}  // namespace mosaicloc::calibration
