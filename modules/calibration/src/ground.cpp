#include "mosaicloc/calibration/ground.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Geometry>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/file.hpp"
#include "mosaicloc/core/yaml.hpp"

namespace mosaicloc::calibration {
namespace {

// The file's keys: the floor frame's columns, the homography's rows and their entries.
constexpr const char* kFloorColumns[] = {"x_axis", "y_axis", "origin_mm"};
constexpr const char* kRows[] = {"row0", "row1", "row2"};
constexpr const char* kEntries[] = {"c0", "c1", "c2"};

Eigen::Matrix3d IdealPixelToFloor(const camera::IdealCameraOptions& ideal) {
  const camera::IdealCamera camera(ideal);
  const double s = ideal.mm_per_px;
  Eigen::Matrix3d a;
  a << s, 0.0, -s * camera.cx(), 0.0, -s, s * camera.cy(), 0.0, 0.0, 1.0;
  return a;
}

Eigen::Matrix3d CameraMatrix(const Intrinsics& k) {
  Eigen::Matrix3d m;
  m << k.fx_px, 0.0, k.cx_px, 0.0, k.fy_px, k.cy_px, 0.0, 0.0, 1.0;
  return m;
}

// Pose of the board in the optical frame from undistorted normalized features (PnP).
bool PoseBoard(const std::vector<Eigen::Vector3d>& board_mm, const std::vector<Eigen::Vector2d>& normalized,
               Eigen::Matrix3d* rotation, Eigen::Vector3d* translation_mm) {
  std::vector<cv::Point3d> object;
  std::vector<cv::Point2d> image;
  for (const Eigen::Vector3d& p : board_mm) object.emplace_back(p.x(), p.y(), p.z());
  for (const Eigen::Vector2d& p : normalized) image.emplace_back(p.x(), p.y());
  cv::Mat rvec, tvec;
  if (!cv::solvePnP(object, image, cv::Mat::eye(3, 3, CV_64F), cv::Mat(), rvec, tvec, false, cv::SOLVEPNP_IPPE)) {
    return false;
  }
  cv::solvePnPRefineLM(object, image, cv::Mat::eye(3, 3, CV_64F), cv::Mat(), rvec, tvec);
  cv::Mat r;
  cv::Rodrigues(rvec, r);
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) (*rotation)(i, j) = r.at<double>(i, j);
    (*translation_mm)(i) = tvec.at<double>(i);
  }
  return translation_mm->z() > 0.0;
}

// Features on the floor against the board's layout. The best 2D similarity q = c R p + t
// (Horn's closed form: with p', q' the centred points, the angle is
// atan2(sum p' x q', sum p' . q') and c = sum q' . R p' / sum |p'|^2) gives the scale error
// c - 1; the residuals are those of the best rigid fit (c = 1, same angle). OpenCV numbers a
// board's features from either end, and may see its numbering from the "back": the layout
// is also tried mirrored and the better fit kept.
IdealBoardMeasurement FitLayout(const Eigen::Matrix2Xd& layout, const Eigen::Matrix2Xd& floor) {
  IdealBoardMeasurement best;
  double best_rms = std::numeric_limits<double>::infinity();
  const Eigen::Vector2d floor_centre = floor.rowwise().mean();
  const Eigen::Matrix2Xd q = floor.colwise() - floor_centre;
  for (const double mirror : {1.0, -1.0}) {
    Eigen::Matrix2Xd source = layout;
    source.row(1) *= mirror;
    const Eigen::Vector2d source_centre = source.rowwise().mean();
    const Eigen::Matrix2Xd p = source.colwise() - source_centre;
    double dot = 0.0, cross = 0.0;
    for (long i = 0; i < p.cols(); ++i) {
      dot += p.col(i).dot(q.col(i));
      cross += p(0, i) * q(1, i) - p(1, i) * q(0, i);
    }
    const Eigen::Matrix2d rotation = Eigen::Rotation2Dd(std::atan2(cross, dot)).toRotationMatrix();
    const Eigen::Matrix2Xd turned = rotation * p;
    const double scale = (turned.array() * q.array()).sum() / p.squaredNorm();
    const Eigen::VectorXd errors = (turned - q).colwise().norm();
    const double rms = std::sqrt(errors.squaredNorm() / static_cast<double>(errors.size()));
    if (rms < best_rms) {
      best_rms = rms;
      best.residual_rms_mm = rms;
      best.residual_max_mm = errors.maxCoeff();
      best.scale_error = scale - 1.0;
    }
  }
  return best;
}

}  // namespace

bool GroundCalibration::Check(std::string* why) const {
  if (!intrinsics.Check(why) || !ideal.Check(why)) return false;
  const Eigen::Vector3d x = optical_from_floor.col(0), y = optical_from_floor.col(1), o = optical_from_floor.col(2);
  if (std::abs(x.norm() - 1.0) > 1e-6 || std::abs(y.norm() - 1.0) > 1e-6 || std::abs(x.dot(y)) > 1e-6) {
    *why = "ground calibration: the floor axes must be orthonormal";
    return false;
  }
  if (!(o.z() > 0.0) || !o.allFinite()) {
    *why = "ground calibration: the floor must lie in front of the camera";
    return false;
  }
  return true;
}

Eigen::Matrix3d GroundCalibration::UndistortedRawFromIdeal() const {
  return CameraMatrix(intrinsics) * optical_from_floor * IdealPixelToFloor(ideal);
}

Eigen::Matrix3d GroundCalibration::IdealFromUndistortedRaw() const {
  const Eigen::Matrix3d h = UndistortedRawFromIdeal().inverse();
  return h / h(2, 2);
}

Eigen::Vector2d GroundCalibration::RawFromIdeal(const Eigen::Vector2d& ideal_px) const {
  const Eigen::Vector3d p_optical = optical_from_floor * IdealPixelToFloor(ideal) * ideal_px.homogeneous();
  return ProjectWithDistortion(intrinsics, p_optical);
}

std::optional<Eigen::Vector2d> GroundCalibration::FloorFromRaw(const Eigen::Vector2d& raw_px) const {
  const Eigen::Vector3d ray = UndistortToNormalized(intrinsics, raw_px).homogeneous();
  const Eigen::Vector3d floor = optical_from_floor.inverse() * ray;  // (X, Y, 1) up to scale
  if (!(floor.z() > 1e-12)) return std::nullopt;
  return Eigen::Vector2d(floor.x() / floor.z(), floor.y() / floor.z());
}

double GroundCalibration::height_mm() const {
  const Eigen::Vector3d up = optical_from_floor.col(0).cross(optical_from_floor.col(1));
  return std::abs(up.dot(optical_from_floor.col(2)));
}

double GroundCalibration::tilt_rad() const {
  const Eigen::Vector3d up = optical_from_floor.col(0).cross(optical_from_floor.col(1));
  return std::acos(std::clamp(-up.z(), -1.0, 1.0));
}

bool GroundOptions::Check(std::string* why) const {
  if (!(mm_per_px > 0.0 && mm_per_px < 100.0)) {
    *why = "ground mm_per_px must be in (0, 100)";
    return false;
  }
  if (width_px < 0 || height_px < 0 || width_px > 16384 || height_px > 16384) {
    *why = "ground width_px and height_px must be 0 (the raw size) or up to 16384";
    return false;
  }
  return true;
}

GroundResult CalibrateGround(const std::vector<BoardView>& views, const camera::BoardSpec& board,
                             const Intrinsics& intrinsics, const GroundOptions& options) {
  std::string why;
  if (!options.Check(&why) || !board.Check(&why) || !intrinsics.Check(&why)) core::ThrowInvalidInput(why);
  if (views.empty()) core::ThrowInvalidInput("ground calibration needs at least one view of the board on the floor");
  const std::vector<Eigen::Vector3d> board_mm = board.FeaturePoints();
  std::vector<Eigen::Vector3d> all_optical;
  std::vector<std::vector<Eigen::Vector2d>> normalized_views;
  for (const BoardView& view : views) {
    if (static_cast<int>(view.detection.points_px.size()) != board.FeatureCount()) {
      core::ThrowInvalidInput(view.name + ": board " + board.ToString() + " not found");
    }
    std::vector<Eigen::Vector2d> normalized;
    for (const Eigen::Vector2d& p : view.detection.points_px) normalized.push_back(UndistortToNormalized(intrinsics, p));
    Eigen::Matrix3d rotation;
    Eigen::Vector3d translation;
    if (!PoseBoard(board_mm, normalized, &rotation, &translation)) {
      core::ThrowInvalidInput(view.name + ": the board's pose cannot be estimated (is it flat and in view?)");
    }
    for (const Eigen::Vector3d& p : board_mm) all_optical.push_back(rotation * p + translation);
    normalized_views.push_back(std::move(normalized));
  }

  // The floor plane n.P = d through every feature (least squares: centroid and the
  // direction of least spread), n oriented towards the camera (d < 0: the camera at the
  // origin is on the side n points to).
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& p : all_optical) centroid += p;
  centroid /= static_cast<double>(all_optical.size());
  // The direction of least spread is the right singular vector of the centred points with the
  // smallest singular value. OpenCV's compiled SVD: Eigen's JacobiSVD template costs about a
  // minute of compilation per translation unit under the sanitizers.
  cv::Mat spread(static_cast<int>(all_optical.size()), 3, CV_64F);
  for (std::size_t i = 0; i < all_optical.size(); ++i) {
    const Eigen::Vector3d d = all_optical[i] - centroid;
    for (int c = 0; c < 3; ++c) spread.at<double>(static_cast<int>(i), c) = d(c);
  }
  cv::Mat singular_values, u, vt;
  cv::SVD::compute(spread, singular_values, u, vt, cv::SVD::MODIFY_A);
  Eigen::Vector3d up(vt.at<double>(2, 0), vt.at<double>(2, 1), vt.at<double>(2, 2));
  if (up.dot(centroid) > 0.0) up = -up;
  GroundResult result;
  double sum_sq = 0.0;
  for (const Eigen::Vector3d& p : all_optical) {
    const double distance = std::abs(up.dot(p - centroid));
    sum_sq += distance * distance;
    result.flatness_max_mm = std::max(result.flatness_max_mm, distance);
  }
  result.flatness_rms_mm = std::sqrt(sum_sq / static_cast<double>(all_optical.size()));

  // Frame C: origin at the nadir, x along the floor projection of the optical x axis.
  const Eigen::Vector3d nadir = up.dot(centroid) * up;
  const Eigen::Vector3d x_axis = (Eigen::Vector3d::UnitX() - up.x() * up).normalized();
  const Eigen::Vector3d y_axis = up.cross(x_axis);
  GroundCalibration& calibration = result.calibration;
  calibration.intrinsics = intrinsics;
  calibration.ideal.width_px = options.width_px > 0 ? options.width_px : intrinsics.width_px;
  calibration.ideal.height_px = options.height_px > 0 ? options.height_px : intrinsics.height_px;
  calibration.ideal.mm_per_px = options.mm_per_px;
  calibration.optical_from_floor.col(0) = x_axis;
  calibration.optical_from_floor.col(1) = y_axis;
  calibration.optical_from_floor.col(2) = nadir;
  if (!calibration.Check(&why)) core::ThrowInvalidInput("ground calibration failed: " + why);

  // Each view's features on the calibrated floor against the board's layout.
  for (std::size_t v = 0; v < views.size(); ++v) {
    Eigen::Matrix2Xd floor(2, board_mm.size()), layout(2, board_mm.size());
    const Eigen::Matrix3d floor_from_optical = calibration.optical_from_floor.inverse();
    for (std::size_t i = 0; i < board_mm.size(); ++i) {
      const Eigen::Vector3d q = floor_from_optical * normalized_views[v][i].homogeneous();
      floor.col(static_cast<long>(i)) = q.head<2>() / q.z();
      layout.col(static_cast<long>(i)) = board_mm[i].head<2>();
    }
    const IdealBoardMeasurement fit = FitLayout(layout, floor);
    GroundViewReport report;
    report.name = views[v].name;
    report.residual_rms_mm = fit.residual_rms_mm;
    report.residual_max_mm = fit.residual_max_mm;
    report.scale_error = fit.scale_error;
    result.views.push_back(report);
  }
  result.coverage = Rectifier(calibration).coverage();
  return result;
}

void BuildRectificationMaps(const GroundCalibration& calibration, cv::Mat* map_x, cv::Mat* map_y) {
  const int width = calibration.ideal.width_px, height = calibration.ideal.height_px;
  map_x->create(height, width, CV_32FC1);
  map_y->create(height, width, CV_32FC1);
  for (int v = 0; v < height; ++v) {
    auto* mx = map_x->ptr<float>(v);
    auto* my = map_y->ptr<float>(v);
    for (int u = 0; u < width; ++u) {
      const Eigen::Vector2d raw = calibration.RawFromIdeal(Eigen::Vector2d(u, v));
      mx[u] = static_cast<float>(raw.x());
      my[u] = static_cast<float>(raw.y());
    }
  }
}

Rectifier::Rectifier(const GroundCalibration& calibration) : calibration_(calibration) {
  std::string why;
  if (!calibration_.Check(&why)) core::ThrowInvalidInput(why);
  BuildRectificationMaps(calibration_, &map_x_, &map_y_);
  const int w = calibration_.intrinsics.width_px, h = calibration_.intrinsics.height_px;
  long inside = 0;
  for (int v = 0; v < map_x_.rows; ++v) {
    for (int u = 0; u < map_x_.cols; ++u) {
      const float x = map_x_.at<float>(v, u), y = map_y_.at<float>(v, u);
      inside += (x >= 0.0f && y >= 0.0f && x <= w - 1.0f && y <= h - 1.0f) ? 1 : 0;
    }
  }
  coverage_ = static_cast<double>(inside) / static_cast<double>(map_x_.total());
}

bool Rectifier::Rectify(const cv::Mat& raw, cv::Mat* ideal) const {
  if (raw.type() != CV_8UC1 || raw.cols != calibration_.intrinsics.width_px ||
      raw.rows != calibration_.intrinsics.height_px) {
    return false;
  }
  cv::remap(raw, *ideal, map_x_, map_y_, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
  return true;
}

void WriteGroundCalibration(const std::filesystem::path& file, const GroundCalibration& c,
                            const std::string& provenance) {
  std::string why;
  if (!c.Check(&why)) core::ThrowInvalidInput(file.string() + ": " + why);
  const Eigen::Matrix3d& m = c.optical_from_floor;
  const Eigen::Matrix3d h = c.IdealFromUndistortedRaw();
  YAML::Emitter yaml;
  yaml.SetDoublePrecision(17);
  yaml << YAML::Comment("mosaicloc ground-plane calibration: turns one camera's raw images into ideal ones\n"
                        "(design.md section 3; the format is described in calib/README.md).\n" +
                        provenance);
  yaml << YAML::BeginMap;
  yaml << YAML::Key << "format_version" << YAML::Value << 1;
  yaml << YAML::Key << "intrinsics" << YAML::Comment("ViSP perspective projection with distortion, pixels");
  yaml << YAML::Value << YAML::BeginMap;
  yaml << YAML::Key << "width_px" << YAML::Value << c.intrinsics.width_px;
  yaml << YAML::Key << "height_px" << YAML::Value << c.intrinsics.height_px;
  yaml << YAML::Key << "fx_px" << YAML::Value << c.intrinsics.fx_px;
  yaml << YAML::Key << "fy_px" << YAML::Value << c.intrinsics.fy_px;
  yaml << YAML::Key << "cx_px" << YAML::Value << c.intrinsics.cx_px;
  yaml << YAML::Key << "cy_px" << YAML::Value << c.intrinsics.cy_px;
  yaml << YAML::Key << "kud" << YAML::Value << c.intrinsics.kud
       << YAML::Comment("undistorted -> distorted, r^2 (normalized)");
  yaml << YAML::Key << "kdu" << YAML::Value << c.intrinsics.kdu
       << YAML::Comment("distorted -> undistorted, r^2 (approximate)");
  yaml << YAML::EndMap;
  yaml << YAML::Key << "ideal" << YAML::Comment("the rectified image: square pixels, principal point at the centre");
  yaml << YAML::Value << YAML::BeginMap;
  yaml << YAML::Key << "width_px" << YAML::Value << c.ideal.width_px;
  yaml << YAML::Key << "height_px" << YAML::Value << c.ideal.height_px;
  yaml << YAML::Key << "mm_per_px" << YAML::Value << c.ideal.mm_per_px;
  yaml << YAML::EndMap;
  yaml << YAML::Key << "floor_in_optical"
       << YAML::Comment("camera floor frame C in the optical frame (x right, y down, z forward)");
  yaml << YAML::Value << YAML::BeginMap;
  const char* notes[] = {"unit vector: image right on the floor", "unit vector: image up on the floor",
                         "the nadir: the floor point below the optical centre, mm"};
  for (int col = 0; col < 3; ++col) {
    yaml << YAML::Key << kFloorColumns[col] << YAML::Value << YAML::Flow << YAML::BeginMap;
    yaml << YAML::Key << "x" << YAML::Value << m(0, col) << YAML::Key << "y" << YAML::Value << m(1, col);
    yaml << YAML::Key << "z" << YAML::Value << m(2, col) << YAML::EndMap << YAML::Comment(notes[col]);
  }
  yaml << YAML::EndMap;
  yaml << YAML::Key << "ideal_from_undistorted_raw"
       << YAML::Comment("homography from undistorted raw pixels to ideal pixels (row-major, h22 = 1); it\n"
                        "follows from the keys above and is checked against them when read");
  yaml << YAML::Value << YAML::BeginMap;
  for (int r = 0; r < 3; ++r) {
    yaml << YAML::Key << kRows[r] << YAML::Value << YAML::Flow << YAML::BeginMap;
    for (int col = 0; col < 3; ++col) yaml << YAML::Key << kEntries[col] << YAML::Value << h(r, col);
    yaml << YAML::EndMap;
  }
  yaml << YAML::EndMap;
  yaml << YAML::Key << "height_mm" << YAML::Value << c.height_mm()
       << YAML::Comment("derived: optical centre above the floor");
  yaml << YAML::Key << "tilt_deg" << YAML::Value << c.tilt_rad() * 180.0 / M_PI
       << YAML::Comment("derived: optical axis to the floor normal");
  yaml << YAML::EndMap;
  if (!yaml.good()) core::ThrowRuntime(file.string() + ": cannot write YAML: " + yaml.GetLastError());
  const std::string out = std::string(yaml.c_str()) + "\n";
  core::WriteFileAtomically(file, out);
}

GroundCalibration ReadGroundCalibration(const std::filesystem::path& file) {
  const YAML::Node node = core::LoadYamlFile(file);
  core::YamlProblems problems;
  core::YamlMap root = core::YamlMap::Root(node, file.string(), &problems);
  GroundCalibration c;
  int version = 0;
  root.Required("format_version", &version, core::IntegerInRange(1, 1));
  core::YamlMap intrinsics = root.RequiredMap("intrinsics");
  intrinsics.Required("width_px", &c.intrinsics.width_px, core::IntegerInRange(8, 16384));
  intrinsics.Required("height_px", &c.intrinsics.height_px, core::IntegerInRange(8, 16384));
  intrinsics.Required("fx_px", &c.intrinsics.fx_px, core::Positive());
  intrinsics.Required("fy_px", &c.intrinsics.fy_px, core::Positive());
  intrinsics.Required("cx_px", &c.intrinsics.cx_px);
  intrinsics.Required("cy_px", &c.intrinsics.cy_px);
  intrinsics.Required("kud", &c.intrinsics.kud, core::InRange(-10.0, 10.0));
  intrinsics.Required("kdu", &c.intrinsics.kdu, core::InRange(-10.0, 10.0));
  intrinsics.Finish();
  core::YamlMap ideal = root.RequiredMap("ideal");
  ideal.Required("width_px", &c.ideal.width_px, core::IntegerInRange(8, 16384));
  ideal.Required("height_px", &c.ideal.height_px, core::IntegerInRange(8, 16384));
  ideal.Required("mm_per_px", &c.ideal.mm_per_px, core::InRange(1e-6, 100.0));
  ideal.Finish();
  core::YamlMap floor = root.RequiredMap("floor_in_optical");
  for (int col = 0; col < 3; ++col) {
    core::YamlMap vector = floor.RequiredMap(kFloorColumns[col]);
    vector.Required("x", &c.optical_from_floor(0, col));
    vector.Required("y", &c.optical_from_floor(1, col));
    vector.Required("z", &c.optical_from_floor(2, col));
    vector.Finish();
  }
  floor.Finish();
  Eigen::Matrix3d stored;
  core::YamlMap homography = root.RequiredMap("ideal_from_undistorted_raw");
  for (int r = 0; r < 3; ++r) {
    core::YamlMap row = homography.RequiredMap(kRows[r]);
    for (int col = 0; col < 3; ++col) row.Required(kEntries[col], &stored(r, col));
    row.Finish();
  }
  homography.Finish();
  double derived = 0.0;
  root.Required("height_mm", &derived);
  root.Required("tilt_deg", &derived);
  root.Finish();
  problems.ThrowIfAny();
  std::string why;
  if (!c.Check(&why)) core::ThrowInvalidInput(file.string() + ": " + why);
  const Eigen::Matrix3d expected = c.IdealFromUndistortedRaw();
  if (!((stored - expected).norm() <= 1e-6 * expected.norm())) {
    core::ThrowInvalidInput(file.string() +
                            ": ideal_from_undistorted_raw does not follow from intrinsics, ideal and "
                            "floor_in_optical (edited by hand?): recalibrate with mosaicloc calibrate ground");
  }
  return c;
}

IdealBoardMeasurement MeasureIdealBoard(const BoardDetection& detection, const camera::BoardSpec& board,
                                        const camera::IdealCameraOptions& ideal) {
  const camera::IdealCamera camera(ideal);
  const std::vector<Eigen::Vector3d> layout_3d = board.FeaturePoints();
  if (detection.points_px.size() != layout_3d.size()) core::ThrowInvalidInput("board detection has the wrong size");
  Eigen::Matrix2Xd floor(2, layout_3d.size()), layout(2, layout_3d.size());
  for (std::size_t i = 0; i < layout_3d.size(); ++i) {
    floor.col(static_cast<long>(i)) = camera.PixelToCamera(detection.points_px[i]);
    layout.col(static_cast<long>(i)) = layout_3d[i].head<2>();
  }
  return FitLayout(layout, floor);
}

}  // namespace mosaicloc::calibration
