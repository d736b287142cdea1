#include "mosaicloc/runtime/map_poses.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <numbers>
#include <optional>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/calibration/flat_field.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/file.hpp"
#include "mosaicloc/core/log.hpp"
#include "mosaicloc/dataset/camera_truth.hpp"
#include "mosaicloc/dataset/dataset.hpp"
#include "mosaicloc/dataset/evaluation.hpp"
#include "mosaicloc/dataset/frame_png.hpp"
#include "mosaicloc/localizer/localizer.hpp"
#include "mosaicloc/runtime/drive.hpp"

namespace mosaicloc::runtime {
namespace {

namespace fs = std::filesystem;

// The best rigid alignment (least squares over the positions, no scale) of `estimate` onto
// `truth`, frame by frame at the same times, and what is left. In 2-D the rotation is the
// angle of the summed cross and dot products of the centred points.
std::optional<AlignedError> Aligned(const std::vector<core::Pose2>& estimate, const std::vector<core::Pose2>& truth) {
  if (estimate.size() < 2) return std::nullopt;
  Eigen::Vector2d mean_from = Eigen::Vector2d::Zero(), mean_to = Eigen::Vector2d::Zero();
  for (std::size_t i = 0; i < estimate.size(); ++i) {
    mean_from += estimate[i].translation_mm();
    mean_to += truth[i].translation_mm();
  }
  mean_from /= static_cast<double>(estimate.size());
  mean_to /= static_cast<double>(estimate.size());
  double dot = 0.0, cross = 0.0;
  for (std::size_t i = 0; i < estimate.size(); ++i) {
    const Eigen::Vector2d p = estimate[i].translation_mm() - mean_from, q = truth[i].translation_mm() - mean_to;
    dot += p.dot(q);
    cross += p.x() * q.y() - p.y() * q.x();
  }
  const double angle = std::atan2(cross, dot);
  const core::Pose2 rotation(0.0, 0.0, angle);
  const core::Pose2 truth_from_estimate(mean_to - rotation.Rotation() * mean_from, angle);
  AlignedError e;
  e.truth_from_estimate = truth_from_estimate;
  double sum = 0.0, sum_yaw = 0.0;
  for (std::size_t i = 0; i < estimate.size(); ++i) {
    const core::Pose2 aligned = truth_from_estimate * estimate[i];
    const double mm = (aligned.translation_mm() - truth[i].translation_mm()).norm();
    const double deg = core::WrapAngle(aligned.yaw_rad() - truth[i].yaw_rad()) * 180.0 / std::numbers::pi;
    sum += mm * mm;
    sum_yaw += deg * deg;
    e.max_mm = std::max(e.max_mm, mm);
  }
  e.rms_mm = std::sqrt(sum / static_cast<double>(estimate.size()));
  e.heading_rms_deg = std::sqrt(sum_yaw / static_cast<double>(estimate.size()));
  return e;
}

struct SeamFigures {
  std::size_t count = 0;
  double before_rms = 0.0, before_max = 0.0, after_rms = 0.0, after_max = 0.0, after_p99 = 0.0;
};

SeamFigures FiguresOf(const std::vector<mapping::Seam>& seams, std::optional<mapping::EdgeKind> kind) {
  SeamFigures f;
  std::vector<double> after;
  double before_sq = 0.0, after_sq = 0.0;
  for (const mapping::Seam& s : seams) {
    if (kind && s.kind != *kind) continue;
    ++f.count;
    before_sq += s.before_px * s.before_px;
    after_sq += s.after_px * s.after_px;
    f.before_max = std::max(f.before_max, s.before_px);
    f.after_max = std::max(f.after_max, s.after_px);
    after.push_back(s.after_px);
  }
  if (f.count == 0) return f;
  f.before_rms = std::sqrt(before_sq / static_cast<double>(f.count));
  f.after_rms = std::sqrt(after_sq / static_cast<double>(f.count));
  std::sort(after.begin(), after.end());
  f.after_p99 = dataset::Percentile(after, 99.0);
  return f;
}

nlohmann::json JsonOf(const SeamFigures& f) {
  return {{"count", f.count},           {"before_rms_px", f.before_rms}, {"before_max_px", f.before_max},
          {"after_rms_px", f.after_rms}, {"after_max_px", f.after_max},   {"after_p99_px", f.after_p99}};
}

// The flat field the frames were registered through: from how many frames, the gain's range.
nlohmann::json JsonOf(const MappingFlatField& field) {
  return {{"frames", field.flat_frames}, {"min_gain", field.min_gain}, {"max_gain", field.max_gain}};
}

nlohmann::json JsonOf(const std::optional<AlignedError>& e) {
  if (!e) return nullptr;
  const core::Pose2& t = e->truth_from_estimate;
  return {{"rms_mm", e->rms_mm},
          {"max_mm", e->max_mm},
          {"heading_rms_deg", e->heading_rms_deg},
          {"truth_from_map", {{"x_mm", t.x_mm()}, {"y_mm", t.y_mm()}, {"yaw_deg", t.yaw_rad() * 180.0 / std::numbers::pi}}}};
}

// Where the map's residuals are: the drive's path, each frame coloured by the largest residual
// of a pair it is in (green under 0.05 px, amber under 0.2 px, red above), accepted loop closures
// as blue lines, rejected ones as red crosses, gaps bridged by the wheels in magenta.
cv::Mat ResidualMap(const MapPosesSummary& summary) {
  const mapping::MappingResult& m = summary.mapping;
  const std::vector<core::Pose2>& nodes = m.graph.nodes;
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  for (const core::Pose2& p : nodes) {
    x0 = std::min(x0, p.x_mm()), x1 = std::max(x1, p.x_mm());
    y0 = std::min(y0, p.y_mm()), y1 = std::max(y1, p.y_mm());
  }
  const int size = 1000, margin = 40;
  const double span = std::max({x1 - x0, y1 - y0, 1.0});
  const double scale = (size - 2 * margin) / span;
  cv::Mat image(size + 40, size, CV_8UC3, cv::Scalar(255, 255, 255));
  auto at = [&](const core::Pose2& p) {
    return cv::Point(static_cast<int>(margin + (p.x_mm() - x0) * scale),
                     static_cast<int>(size - margin - (p.y_mm() - y0) * scale));
  };
  std::vector<double> worst(nodes.size(), 0.0);
  for (const mapping::Seam& s : m.seams) {
    worst[s.from] = std::max(worst[s.from], s.after_px);
    worst[s.to] = std::max(worst[s.to], s.after_px);
  }
  for (std::size_t i = 1; i < nodes.size(); ++i) cv::line(image, at(nodes[i - 1]), at(nodes[i]), {200, 200, 200}, 3);
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    const cv::Scalar colour = worst[i] < 0.05 ? cv::Scalar(60, 170, 60)
                              : worst[i] < 0.2 ? cv::Scalar(0, 160, 255)
                                               : cv::Scalar(0, 0, 220);
    cv::circle(image, at(nodes[i]), worst[i] < 0.05 ? 1 : 3, colour, cv::FILLED);
  }
  for (const mapping::MappingGap& g : m.gaps) {
    for (int i = std::max(g.first, 1); i <= g.last; ++i) cv::line(image, at(nodes[i - 1]), at(nodes[i]), {200, 0, 200}, 3);
  }
  for (const mapping::LoopClosure& l : m.loops) {
    if (l.accepted) {
      cv::line(image, at(nodes[l.earlier]), at(nodes[l.later]), {200, 80, 0}, 1);
    } else if (!l.rejected.empty() && l.inliers > 0) {
      cv::drawMarker(image, at(nodes[l.later]), {0, 0, 220}, cv::MARKER_TILTED_CROSS, 9, 2);
    }
  }
  char text[200];
  std::snprintf(text, sizeof text, "%zu loops closed, %zu gaps; seams after optimization: green < 0.05 px, amber < 0.2, red",
                static_cast<std::size_t>(m.loops_accepted), m.gaps.size());
  cv::putText(image, text, {10, size + 25}, cv::FONT_HERSHEY_SIMPLEX, 0.5, {0, 0, 0}, 1, cv::LINE_AA);
  return image;
}

// A pose graph read from a g2o file, solved, as the drive's poses.
mapping::MappingResult OptimizeImported(const fs::path& file, const mapping::MappingInput& input,
                                        const mapping::MapperOptions& options) {
  mapping::MappingResult m;
  m.graph = mapping::ReadG2o(file);
  const std::size_t n = input.frame_times.size();
  if (m.graph.nodes.size() != n) {
    core::ThrowInvalidInput(file.string() + ": " + std::to_string(m.graph.nodes.size()) + " nodes for the drive's " +
                            std::to_string(n) + " frames");
  }
  std::vector<core::Pose2> before = m.graph.nodes;
  m.optimize = mapping::Optimize(m.graph, options.optimize);
  m.pieces = m.optimize.pieces;
  m.frames = static_cast<std::int64_t>(n);
  m.has_pose.assign(n, 1);
  for (std::size_t i = 0; i < n; ++i) {
    m.world_from_vehicle.push_back(m.graph.nodes[i] * input.vehicle_from_camera.Inverse());
    m.chained_world_from_vehicle.push_back(before[i] * input.vehicle_from_camera.Inverse());
    if (i > 0) m.path_length_m += 1e-3 * (m.graph.nodes[i].translation_mm() - m.graph.nodes[i - 1].translation_mm()).norm();
  }
  for (const mapping::PoseGraphEdge& e : m.graph.edges) m.loops_accepted += e.kind == mapping::EdgeKind::kLoop ? 1 : 0;
  if (options.view_geometry) {
    m.warnings.push_back("the imported graph's edges are taken as they are: the camera's height and tilt are "
                         "measured from the frames' registrations, which a graph does not carry (a graph this "
                         "program exported has them taken out already)");
  }
  return m;
}

}  // namespace

nlohmann::json MapPosesSummary::ToJson() const {
  const mapping::MappingResult& m = mapping;
  const SeamFigures seams = FiguresOf(m.seams, std::nullopt);
  return {{"frames", m.frames},
          {"drives", poses.size()},
          {"pieces", m.pieces},
          {"path_length_m", m.path_length_m},
          {"registered", m.registered},
          {"loops_tried", m.loops_tried},
          {"loops_accepted", m.loops_accepted},
          {"gaps", m.gaps.size()},
          {"seam_rms_px", seams.after_rms},
          {"seam_max_px", seams.after_max},
          {"seconds", seconds},
          {"flat_field", JsonOf(flat_field)},
          {"vs_groundtruth", JsonOf(error)},
          {"chained_vs_groundtruth", JsonOf(chained_error)},
          {"warnings", m.warnings}};
}

mapping::MapperOptions DefaultMapperOptions() {
  mapping::MapperOptions options;
  options.tracker = localizer::LocalizerOptions{}.tracker;
  options.tracker.templates.count = 16;
  return options;
}

fs::path DrivePath(const fs::path& out, int k) {
  if (k <= 1) return out;
  fs::path path = out;
  return path.replace_extension("." + std::to_string(k) + out.extension().string());
}

MappingFlatField EstimateMappingFlatField(const std::function<cv::Mat(std::size_t)>& load_frame,
                                          const std::vector<core::Pose2>& wheels,
                                          const std::vector<std::size_t>& first_of_drive, double spacing_mm,
                                          int max_frames, int min_frames) {
  // The wheels' travel along every drive, each from its start (drives' wheels share no origin).
  std::vector<char> starts(wheels.size(), 0);
  for (const std::size_t first : first_of_drive) {
    if (first < starts.size()) starts[first] = 1;
  }
  if (!starts.empty()) starts[0] = 1;
  std::vector<double> travel(wheels.size(), 0.0);
  for (std::size_t i = 1; i < wheels.size(); ++i) {
    travel[i] = travel[i - 1] + (starts[i] ? 0.0 : core::Distance(wheels[i - 1], wheels[i]));
  }
  const int spread = std::max(max_frames - static_cast<int>(first_of_drive.size()), 1);
  const double spacing = std::max(spacing_mm, (travel.empty() ? 0.0 : travel.back()) / spread);
  std::vector<std::size_t> chosen;
  double last = 0.0;
  for (std::size_t i = 0; i < wheels.size(); ++i) {
    if (!starts[i] && travel[i] - last < spacing) continue;
    chosen.push_back(i);
    last = travel[i];
  }
  MappingFlatField field;
  if (chosen.size() < static_cast<std::size_t>(min_frames)) return field;
  calibration::FlatFieldEstimator estimator;
  for (const std::size_t i : chosen) {
    const cv::Mat image = load_frame(i);
    if (!image.empty()) estimator.Add(image);
  }
  if (estimator.frames() < min_frames) return field;
  field.gain = estimator.Gain();
  field.flat_frames = estimator.frames();
  cv::minMaxLoc(field.gain, &field.min_gain, &field.max_gain);
  return field;
}

MapPosesSummary EstimateMapPoses(const MapPosesOptions& options, const std::function<void(double)>& progress) {
  std::vector<std::unique_ptr<dataset::DatasetReader>> opened;
  std::vector<const dataset::DatasetReader*> readers;
  opened.push_back(std::make_unique<dataset::DatasetReader>(options.dataset));
  for (const fs::path& d : options.joined) opened.push_back(std::make_unique<dataset::DatasetReader>(d));
  for (const auto& reader : opened) readers.push_back(reader.get());
  return EstimateMapPoses(options, readers, progress);
}

MapPosesSummary EstimateMapPoses(const MapPosesOptions& options, const std::vector<const dataset::DatasetReader*>& readers,
                                 const std::function<void(double)>& progress) {
  const auto started = std::chrono::steady_clock::now();
  std::vector<fs::path> datasets = {options.dataset};
  datasets.insert(datasets.end(), options.joined.begin(), options.joined.end());
  if (readers.size() != datasets.size()) core::ThrowInvalidInput("map poses: one reader per drive is needed");
  if (!options.graph_in.empty() && datasets.size() > 1) {
    core::ThrowInvalidInput("an imported pose graph is of one drive: it cannot be joined with others");
  }
  MapPosesSummary summary;
  mapping::MappingInput input;
  std::vector<fs::path> files;
  std::vector<std::optional<dataset::Trajectory>> truths;
  std::vector<std::size_t> firsts;  // per drive, its first frame in the input
  for (std::size_t d = 0; d < datasets.size(); ++d) {
    const dataset::DatasetReader& reader = *readers[d];
    const dataset::DatasetInfo& info = reader.info();
    const camera::IdealCamera camera = CameraOf(info);
    if (d == 0) {
      input.camera = camera;
      input.vehicle_from_camera = info.camera.vehicle_from_camera;
    } else if (camera.width_px() != input.camera.width_px() || camera.height_px() != input.camera.height_px() ||
               camera.mm_per_px() != input.camera.mm_per_px() ||
               core::Distance(info.camera.vehicle_from_camera, input.vehicle_from_camera) > 1e-9 ||
               info.camera.vehicle_from_camera.yaw_rad() != input.vehicle_from_camera.yaw_rad()) {
      core::ThrowInvalidInput(datasets[d].string() + ": its camera (size, mm_per_px or mounting) is not " +
                              datasets[0].string() + "'s: drives mapped together must share one camera");
    }
    // The registrations measure where the camera looked: the truth they are held against is that.
    truths.push_back(reader.HasGroundTruth() ? std::optional(ViewTruthOf(datasets[d], reader).world_from_vehicle)
                                             : std::nullopt);
    std::int64_t rejected = 0;
    const dataset::Trajectory wheels = WheelTrajectory(reader, core::Pose2::Identity(), &rejected);
    summary.encoder_samples_rejected += rejected;
    std::int64_t without_wheels = 0;
    const std::size_t first = input.frame_times.size();
    for (auto frames = reader.Frames(); const auto frame = frames.Next(false);) {
      const auto wheel = dataset::PoseAt(wheels, frame->time, std::chrono::milliseconds(100));
      if (!wheel) {
        ++without_wheels;
        continue;
      }
      input.frame_times.push_back(frame->time);
      input.wheels.push_back(*wheel);
      files.push_back(frame->path);
    }
    if (input.frame_times.size() == first) {
      core::ThrowInvalidInput(datasets[d].string() + ": no frame has encoder data");
    }
    if (without_wheels > 0) {
      core::Log().warn("{}: {} frames without encoder data around them are not mapped", datasets[d].string(),
                       without_wheels);
    }
    firsts.push_back(first);
    const core::Pose2 start = d == 0 && options.start ? *options.start
                                                      : StartPose(truths.back(), info, input.frame_times[first]);
    if (d == 0) {
      input.start = start;
    } else {
      input.later_drives.push_back(
          {static_cast<int>(first), start, options.join_start_sigma_mm, options.join_start_sigma_deg});
    }
  }
  firsts.push_back(input.frame_times.size());
  // A frame that cannot be read stops the mapping, naming it, as it stops the painting: a
  // damaged recording is repaired, not mapped around.
  const int width = input.camera.width_px(), height = input.camera.height_px();
  input.load_frame = [&files, width, height](std::size_t i) {
    cv::Mat image = dataset::ReadImageFile(files[i]);
    if (image.empty()) core::ThrowInvalidInput("image " + files[i].string() + " cannot be decoded");
    if (image.type() != CV_8UC1 || image.cols != width || image.rows != height) {
      core::ThrowInvalidInput("image " + files[i].string() + " is not a " + std::to_string(width) + "x" +
                              std::to_string(height) + " 8-bit grey image as dataset.yaml says");
    }
    return image;
  };
  std::optional<std::string> flat_field_warning;
  if (options.flat_field && options.graph_in.empty()) {
    // Frames at least a view's width apart show other floor: their median is the camera's own.
    const double view_mm = input.camera.width_px() * input.camera.mm_per_px();
    std::vector<std::size_t> starts(firsts.begin(), firsts.end() - 1);
    summary.flat_field = EstimateMappingFlatField(input.load_frame, input.wheels, starts, view_mm);
    if (summary.flat_field.gain.empty()) {
      flat_field_warning = "the drive shows too little floor for the camera's flat field (fewer than 24 frames a "
                           "view's width apart): its frames were registered as they are, so a vignetting camera's "
                           "chain is bent by it";
    } else {
      input.load_frame = [read = input.load_frame, gain = summary.flat_field.gain](std::size_t i) {
        return calibration::DivideByGain(read(i), gain);
      };
    }
  }
  if (options.graph_in.empty()) {
    summary.mapping = mapping::MapPoses(input, options.mapper, progress);
  } else {
    summary.mapping = OptimizeImported(options.graph_in, input, options.mapper);
  }
  if (flat_field_warning) summary.mapping.warnings.insert(summary.mapping.warnings.begin(), *flat_field_warning);
  const mapping::MappingResult& m = summary.mapping;
  std::vector<core::Pose2> estimate, chained, truth;
  for (std::size_t d = 0; d + 1 < firsts.size(); ++d) {
    dataset::Trajectory& poses = summary.poses.emplace_back();
    for (std::size_t i = firsts[d]; i < firsts[d + 1]; ++i) {
      if (!m.has_pose[i]) continue;
      poses.push_back({input.frame_times[i], m.world_from_vehicle[i]});
      if (!truths[d]) continue;
      const auto t = dataset::PoseAt(*truths[d], input.frame_times[i], std::chrono::milliseconds(100));
      if (!t) continue;
      estimate.push_back(m.world_from_vehicle[i]);
      chained.push_back(m.chained_world_from_vehicle[i]);
      truth.push_back(*t);
    }
  }
  summary.error = Aligned(estimate, truth);
  summary.chained_error = Aligned(chained, truth);
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  for (const std::string& warning : m.warnings) core::Log().warn("{}: {}", options.dataset.string(), warning);
  if (!options.out.empty()) {
    for (std::size_t d = 0; d < summary.poses.size(); ++d) {
      dataset::WriteTum(DrivePath(options.out, static_cast<int>(d) + 1), summary.poses[d]);
    }
  }
  if (!options.views_out.empty()) {
    const bool applied = m.view.height_applied || m.view.tilt_applied;
    const double height_mm = options.mapper.tracker.solver.camera_height_mm;
    for (std::size_t d = 0; d + 1 < firsts.size(); ++d) {
      const fs::path file = DrivePath(options.views_out, static_cast<int>(d) + 1);
      std::error_code ec;
      if (!applied) {
        fs::remove(file, ec);
        continue;
      }
      // The mapper's tilt is the floor's slope in image axes (x right, y down); the camera's
      // is about its own x and y axes (y up): tilt_x = -slope_y, tilt_y = -slope_x.
      std::string rows = dataset::CameraTruthHeader();
      for (std::size_t i = firsts[d]; i < firsts[d + 1]; ++i) {
        if (!m.has_pose[i]) continue;
        dataset::CameraTruth view;
        view.height_mm = m.view.scale[i] * height_mm;
        view.tilt_x_rad = -m.view.tilt[i].y();
        view.tilt_y_rad = -m.view.tilt[i].x();
        rows += dataset::CameraTruthRow(input.frame_times[i], view);
      }
      core::WriteFileAtomically(file, rows);
    }
  }
  if (!options.graph_out.empty()) mapping::WriteG2o(options.graph_out, m.graph);
  if (!options.report.empty()) WriteMappingReport(options.report, summary);
  return summary;
}

void WriteMappingReport(const fs::path& directory, const MapPosesSummary& summary) {
  std::error_code ec;
  fs::create_directories(directory, ec);
  if (ec) core::ThrowRuntime(directory.string() + ": cannot be created (" + ec.message() + ")");
  const mapping::MappingResult& m = summary.mapping;
  const double frames = static_cast<double>(m.frames);
  nlohmann::json loops_rejected = nlohmann::json::object();
  for (const mapping::LoopClosure& l : m.loops) {
    if (l.accepted) continue;
    loops_rejected[l.rejected_by] = loops_rejected.value(l.rejected_by, 0) + 1;
  }
  nlohmann::json gaps = nlohmann::json::array();
  for (const mapping::MappingGap& g : m.gaps) gaps.push_back({{"first", g.first}, {"last", g.last}, {"length_mm", g.length_mm}});
  const nlohmann::json report = {
      {"frames", m.frames},
      {"path_length_m", m.path_length_m},
      {"registered", m.registered},
      {"keyframe_edges", m.keyframe_edges},
      {"loops_tried", m.loops_tried},
      {"loops_accepted", m.loops_accepted},
      {"loops_rejected", loops_rejected},
      {"gaps", gaps},
      {"pieces", m.pieces},
      {"view_geometry",
       m.view.scale.empty()
           ? nlohmann::json(nullptr)
           : nlohmann::json{{"height_agreement", m.view.height_agreement},
                            {"tilt_agreement", {m.view.tilt_agreement.x(), m.view.tilt_agreement.y()}},
                            {"height_applied", m.view.height_applied},
                            {"tilt_applied", m.view.tilt_applied}}},
      {"warnings", m.warnings},
      {"seams", JsonOf(FiguresOf(m.seams, std::nullopt))},
      {"sequential_seams", JsonOf(FiguresOf(m.seams, mapping::EdgeKind::kSequential))},
      {"loop_seams", JsonOf(FiguresOf(m.seams, mapping::EdgeKind::kLoop))},
      {"optimization",
       {{"converged", m.optimize.converged},
        {"iterations", m.optimize.iterations},
        {"initial_cost", m.optimize.initial_cost},
        {"final_cost", m.optimize.final_cost},
        {"graph_pieces", m.optimize.pieces},
        {"seconds", m.optimize_seconds}}},
      {"register_fps", m.register_seconds > 0 ? frames / m.register_seconds : 0.0},
      {"loop_fps", m.loop_seconds > 0 ? frames / m.loop_seconds : 0.0},
      {"total_seconds", summary.seconds},
      {"flat_field", JsonOf(summary.flat_field)},
      {"vs_groundtruth", JsonOf(summary.error)},
      {"chained_vs_groundtruth", JsonOf(summary.chained_error)}};
  core::WriteFileAtomically(directory / "consistency.json", report.dump(2) + "\n");

  std::ostringstream loops;
  loops << "#earlier,later,accepted,correction_mm,chi2,mean_zncc,inliers,reason\n";
  for (const mapping::LoopClosure& l : m.loops) {
    std::string reason = l.rejected;
    std::replace(reason.begin(), reason.end(), ',', ';');
    loops << l.earlier << ',' << l.later << ',' << (l.accepted ? 1 : 0) << ',' << l.correction_mm << ',' << l.chi2
          << ',' << l.mean_zncc << ',' << l.inliers << ',' << reason << '\n';
  }
  core::WriteFileAtomically(directory / "loops.csv", loops.str());
  std::ostringstream seams;
  seams << "#from,to,kind,before_px,after_px\n";
  for (const mapping::Seam& s : m.seams) {
    seams << s.from << ',' << s.to << ',' << mapping::ToString(s.kind) << ',' << s.before_px << ',' << s.after_px << '\n';
  }
  core::WriteFileAtomically(directory / "seams.csv", seams.str());
  // The path with each frame's worst seam after optimization: where the lanes were mapped and
  // how well they fit, for the console's layer.
  std::vector<double> worst_seam(m.world_from_vehicle.size(), 0.0);
  for (const mapping::Seam& s : m.seams) {
    for (const int frame : {s.from, s.to}) {
      if (frame >= 0 && static_cast<std::size_t>(frame) < worst_seam.size()) {
        worst_seam[static_cast<std::size_t>(frame)] = std::max(worst_seam[static_cast<std::size_t>(frame)], s.after_px);
      }
    }
  }
  std::ostringstream path;
  path.precision(10);
  path << "#frame,x_mm,y_mm,yaw_rad,worst_seam_px\n";
  for (std::size_t i = 0; i < m.world_from_vehicle.size(); ++i) {
    if (i < m.has_pose.size() && !m.has_pose[i]) continue;
    const core::Pose2& p = m.world_from_vehicle[i];
    path << i << ',' << p.x_mm() << ',' << p.y_mm() << ',' << p.yaw_rad() << ',' << worst_seam[i] << '\n';
  }
  core::WriteFileAtomically(directory / "path.csv", path.str());
  // Each frame's camera over the floor under it, as the registrations measured it.
  if (!m.view.scale.empty()) {
    std::ostringstream view;
    view.precision(10);
    view << "#frame,height_scale,tilt_x_rad,tilt_y_rad\n";
    for (std::size_t i = 0; i < m.view.scale.size(); ++i) {
      if (i < m.has_pose.size() && !m.has_pose[i]) continue;
      view << i << ',' << m.view.scale[i] << ',' << m.view.tilt[i].x() << ',' << m.view.tilt[i].y() << '\n';
    }
    core::WriteFileAtomically(directory / "view.csv", view.str());
  } else {
    fs::remove(directory / "view.csv", ec);  // one from an earlier report in this folder would mislead
  }
  std::vector<uchar> png;
  if (!cv::imencode(".png", ResidualMap(summary), png)) core::ThrowRuntime("residuals.png: cannot be encoded");
  core::WriteFileAtomically(directory / "residuals.png",
                            std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
}

}  // namespace mosaicloc::runtime
