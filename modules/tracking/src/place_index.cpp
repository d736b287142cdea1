#include "mosaicloc/tracking/place_index.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <numbers>
#include <random>
#include <unordered_map>
#include <unordered_set>

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/mosaic/renderer.hpp"
#include "mosaicloc/mosaic/tile_cache.hpp"
#include "binary_erode.hpp"

namespace mosaicloc::tracking {
namespace {

constexpr int kDescriptorBytes = 32;
// A record: x_mm, y_mm, yaw of the corner's orientation in the world (float32 each, the
// host's byte order, little-endian on every platform the project builds for), then the
// 32-byte descriptor.
constexpr std::size_t kRecordBytes = kPlaceRecordBytes;
// Pixels around a corner its descriptor reads (ORB's 31 px patch, rotated: the radius of its
// circumscribed circle).
constexpr int kPatchRadius = 22;
// Each side of a tile or frame is split into this many blocks, and the strongest corners of
// each block are kept, so that a tile's corners cover it instead of crowding its busiest part.
constexpr int kBlocks = 4;

cv::Ptr<cv::ORB> Detector(const PlaceIndexOptions& options, int features) {
  // One scale: the map and the frame are brought to the same resolution. The edge threshold
  // only keeps corners whose patch lies in the image; the caller's margins and masks do the rest.
  return cv::ORB::create(std::max(features, 1), 1.2F, 1, 31, 0, 2, cv::ORB::HARRIS_SCORE, 31, options.fast_threshold);
}

// The strongest corners of each of kBlocks x kBlocks blocks of `area`, at most `total` in all.
std::vector<cv::KeyPoint> Spread(const std::vector<cv::KeyPoint>& corners, const cv::Rect& area, int total) {
  const int per_block = std::max(1, total / (kBlocks * kBlocks));
  std::vector<std::vector<cv::KeyPoint>> blocks(kBlocks * kBlocks);
  for (const cv::KeyPoint& k : corners) {
    const int bx = static_cast<int>(std::floor((k.pt.x - area.x) * kBlocks / area.width));
    const int by = static_cast<int>(std::floor((k.pt.y - area.y) * kBlocks / area.height));
    if (bx < 0 || by < 0 || bx >= kBlocks || by >= kBlocks) continue;
    blocks[static_cast<std::size_t>(by * kBlocks + bx)].push_back(k);
  }
  std::vector<cv::KeyPoint> kept;
  for (auto& block : blocks) {
    const auto n = std::min<std::size_t>(block.size(), static_cast<std::size_t>(per_block));
    std::partial_sort(block.begin(), block.begin() + static_cast<std::ptrdiff_t>(n), block.end(),
                      [](const cv::KeyPoint& a, const cv::KeyPoint& b) { return a.response > b.response; });
    kept.insert(kept.end(), block.begin(), block.begin() + static_cast<std::ptrdiff_t>(n));
  }
  return kept;
}

// The corner's orientation in a frame whose y axis points up (the world's, the camera's) from
// OpenCV's angle in image axes (degrees, y down).
double UpAngle(const cv::KeyPoint& k) { return -k.angle * std::numbers::pi / 180.0; }

double Wrap(double a) {
  a = std::fmod(a, 2.0 * std::numbers::pi);
  return a < 0.0 ? a + 2.0 * std::numbers::pi : a;
}

// A rigid motion of the floor plane: world = R(yaw) camera + t.
struct Rigid {
  double yaw = 0.0;
  Eigen::Vector2d t = Eigen::Vector2d::Zero();
  Eigen::Vector2d Apply(const Eigen::Vector2d& p) const {
    const double c = std::cos(yaw), s = std::sin(yaw);
    return {c * p.x() - s * p.y() + t.x(), s * p.x() + c * p.y() + t.y()};
  }
};

// The least-squares rigid motion taking `from` onto `to` (2-D Procrustes).
Rigid Fit(const std::vector<Eigen::Vector2d>& from, const std::vector<Eigen::Vector2d>& to) {
  Eigen::Vector2d mean_from = Eigen::Vector2d::Zero(), mean_to = Eigen::Vector2d::Zero();
  for (std::size_t i = 0; i < from.size(); ++i) {
    mean_from += from[i];
    mean_to += to[i];
  }
  mean_from /= static_cast<double>(from.size());
  mean_to /= static_cast<double>(to.size());
  double sin_sum = 0.0, cos_sum = 0.0;
  for (std::size_t i = 0; i < from.size(); ++i) {
    const Eigen::Vector2d a = from[i] - mean_from, b = to[i] - mean_to;
    cos_sum += a.dot(b);
    sin_sum += a.x() * b.y() - a.y() * b.x();
  }
  Rigid r;
  r.yaw = std::atan2(sin_sum, cos_sum);
  r.t = mean_to - Rigid{r.yaw, Eigen::Vector2d::Zero()}.Apply(mean_from);
  return r;
}

}  // namespace

namespace internal {

// Locality-sensitive hashing of 256-bit descriptors by bit sampling: each table keys a feature
// by some of its descriptor's bits, drawn once from a seeded generator (the same map gives the
// same index and the same answers). A table is one sorted array of (key, feature) pairs, eight
// bytes a feature: FLANN's LSH kept a hash map node per feature and table, 1 GiB for a 90 m
// map where this takes 70 MiB.
class BitSamplingLsh {
 public:
  BitSamplingLsh(const cv::Mat& descriptors, int tables, int bits) : descriptors_(descriptors) {
    std::mt19937 random(0x5eed);
    std::vector<int> all(kDescriptorBytes * 8);
    for (int i = 0; i < static_cast<int>(all.size()); ++i) all[static_cast<std::size_t>(i)] = i;
    for (int t = 0; t < tables; ++t) {
      std::shuffle(all.begin(), all.end(), random);
      positions_.emplace_back(all.begin(), all.begin() + bits);
      std::vector<std::uint64_t> entries(static_cast<std::size_t>(descriptors.rows));
      for (int f = 0; f < descriptors.rows; ++f) {
        entries[static_cast<std::size_t>(f)] =
            (static_cast<std::uint64_t>(Key(descriptors.ptr(f), positions_.back())) << 32) | static_cast<std::uint32_t>(f);
      }
      std::sort(entries.begin(), entries.end());
      entries_.push_back(std::move(entries));
    }
  }

  // The k nearest features (Hamming distance, then index) among those sharing a key with the
  // query in some table, as (distance, feature).
  std::vector<std::pair<int, int>> Nearest(const std::uint8_t* query, int k) const {
    std::vector<int> candidates;
    for (std::size_t t = 0; t < entries_.size(); ++t) {
      const std::uint64_t key = static_cast<std::uint64_t>(Key(query, positions_[t])) << 32;
      const auto& entries = entries_[t];
      for (auto it = std::lower_bound(entries.begin(), entries.end(), key);
           it != entries.end() && (*it >> 32) == (key >> 32); ++it) {
        candidates.push_back(static_cast<int>(*it & 0xFFFFFFFFU));
      }
    }
    std::sort(candidates.begin(), candidates.end());
    candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
    std::vector<std::pair<int, int>> nearest;
    nearest.reserve(candidates.size());
    for (const int f : candidates) nearest.emplace_back(Hamming(query, descriptors_.ptr(f)), f);
    const auto n = std::min<std::size_t>(nearest.size(), static_cast<std::size_t>(k));
    std::partial_sort(nearest.begin(), nearest.begin() + static_cast<std::ptrdiff_t>(n), nearest.end());
    nearest.resize(n);
    return nearest;
  }

  std::size_t bytes() const {
    std::size_t total = 0;
    for (const auto& entries : entries_) total += entries.size() * sizeof(std::uint64_t);
    return total;
  }

 private:
  static std::uint32_t Key(const std::uint8_t* descriptor, const std::vector<int>& positions) {
    std::uint32_t key = 0;
    for (const int bit : positions) key = (key << 1) | ((descriptor[bit >> 3] >> (bit & 7)) & 1U);
    return key;
  }
  static int Hamming(const std::uint8_t* a, const std::uint8_t* b) {
    int distance = 0;
    for (int i = 0; i < kDescriptorBytes; i += 8) {
      std::uint64_t x = 0, y = 0;
      std::memcpy(&x, a + i, 8);
      std::memcpy(&y, b + i, 8);
      distance += __builtin_popcountll(x ^ y);
    }
    return distance;
  }

  const cv::Mat& descriptors_;
  std::vector<std::vector<int>> positions_;
  std::vector<std::vector<std::uint64_t>> entries_;
};

}  // namespace internal

bool PlaceIndexOptions::Check(std::string* why) const {
  auto fail = [why](const char* message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (level < 0 || level > 4) return fail("place index level must be in [0, 4]");
  if (features_per_tile < kBlocks * kBlocks) return fail("place index features_per_tile must be at least 16");
  if (frame_features < kBlocks * kBlocks) return fail("place index frame_features must be at least 16");
  if (fast_threshold < 1 || fast_threshold > 100) return fail("place index fast_threshold must be in [1, 100]");
  if (neighbours < 1 || neighbours > 16) return fail("place index neighbours must be in [1, 16]");
  if (lsh_tables < 1 || lsh_tables > 32) return fail("place index lsh_tables must be in [1, 32]");
  if (lsh_key_bits < 8 || lsh_key_bits > 32) return fail("place index lsh_key_bits must be in [8, 32]");
  if (max_hamming < 1 || max_hamming > 256) return fail("place index max_hamming must be in [1, 256]");
  if (!(bin_mm > 0.0) || !(bin_deg > 0.0 && bin_deg <= 180.0)) return fail("place index bins must be positive");
  if (!(inlier_mm > 0.0)) return fail("place index inlier_mm must be > 0");
  if (min_inliers < 3) return fail("place index min_inliers must be at least 3");
  if (max_candidates < 1) return fail("place index max_candidates must be at least 1");
  return true;
}

mosaic::PlaceIndexInfo PlaceIndexInfoFor(const PlaceIndexOptions& options) {
  mosaic::PlaceIndexInfo info;
  info.format_version = kPlaceIndexFormatVersion;
  info.method = kPlaceIndexMethod;
  info.level = options.level;
  return info;
}

std::vector<mosaic::PlaceCell> BuildPlaceCells(const mosaic::TileStore& store, const PlaceIndexOptions& options,
                                               const std::function<void(double)>& progress) {
  std::string why;
  if (!options.Check(&why)) core::ThrowInvalidInput("place index options: " + why);
  const mosaic::MapGrid& grid = store.grid();
  if (options.level >= grid.levels) {
    core::ThrowInvalidInput(store.file().string() + ": the place index's level " + std::to_string(options.level) +
                            " is not below the map's " + std::to_string(grid.levels) + " levels");
  }
  mosaic::TileCache cache(store, std::size_t{64} << 20);
  const mosaic::MapRenderer renderer(cache);
  const std::vector<mosaic::TileKey> keys = store.List(options.level);
  const cv::Ptr<cv::ORB> orb = Detector(options, 4 * options.features_per_tile);
  const int t = grid.tile_size_px;
  const int margin = kPatchRadius + 10;
  const cv::Mat within = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * kPatchRadius + 1, 2 * kPatchRadius + 1));
  std::vector<mosaic::PlaceCell> cells;
  for (std::size_t n = 0; n < keys.size(); ++n) {
    const mosaic::TileKey& key = keys[n];
    const mosaic::RasterPatch patch =
        renderer.Region(options.level, key.col * t - margin, key.row * t - margin, t + 2 * margin, t + 2 * margin);
    // Corners only where the whole patch their descriptor reads is mapped floor: a lane's
    // edge is not floor texture.
    cv::Mat usable;
    detail::ErodeBinary(patch.mask, within, &usable);
    std::vector<cv::KeyPoint> corners;
    orb->detect(patch.image, corners, usable);
    corners = Spread(corners, cv::Rect(margin, margin, t, t), options.features_per_tile);
    cv::Mat descriptors;
    orb->compute(patch.image, corners, descriptors);
    mosaic::PlaceCell cell;
    cell.col = key.col;
    cell.row = key.row;
    cell.data.resize(corners.size() * kRecordBytes);
    for (std::size_t i = 0; i < corners.size(); ++i) {
      const Eigen::Vector2d world = grid.RasterToWorld(
          {static_cast<double>(patch.col0) + corners[i].pt.x, static_cast<double>(patch.row0) + corners[i].pt.y},
          options.level);
      const float values[3] = {static_cast<float>(world.x()), static_cast<float>(world.y()),
                               static_cast<float>(UpAngle(corners[i]))};
      unsigned char* out = cell.data.data() + i * kRecordBytes;
      std::memcpy(out, values, sizeof(values));
      std::memcpy(out + sizeof(values), descriptors.ptr(static_cast<int>(i)), kDescriptorBytes);
    }
    if (!corners.empty()) cells.push_back(std::move(cell));
    if (progress) progress(static_cast<double>(n + 1) / static_cast<double>(keys.size()));
  }
  return cells;
}

struct PlaceIndex::Loaded {
  std::vector<Eigen::Vector2f> world_mm;
  std::vector<float> angle;
  cv::Mat descriptors;  // CV_8U, one row of 32 bytes per feature
  std::unique_ptr<internal::BitSamplingLsh> search;
  double seconds = 0.0;
};

PlaceIndex::PlaceIndex(const mosaic::TileStore& store, const PlaceIndexOptions& options)
    : store_(store), options_(options) {
  std::string why;
  if (!options_.Check(&why)) core::ThrowInvalidInput("place index options: " + why);
  try {
    const auto info = store_.Places();
    if (!info) {
      problem_ = store_.file().string() + " has no place index: build it with `mosaicloc map index " +
                 store_.file().string() + "`";
    } else if (info->format_version != kPlaceIndexFormatVersion || info->method != kPlaceIndexMethod) {
      problem_ = store_.file().string() + ": its place index is of another format (version " +
                 std::to_string(info->format_version) + ", " + info->method + "): rebuild it with `mosaicloc map index`";
    } else {
      options_.level = info->level;
      // The floor's self-test: copies found elsewhere say it repeats; views all found at their
      // own place say it does not; no test, or nothing placed, leaves it unknown.
      if (info->repeat_test_elsewhere > 0) {
        floor_repeats_ = true;
      } else if (info->repeat_test_elsewhere == 0 && info->repeat_test_own > 0) {
        floor_repeats_ = false;
      }
    }
  } catch (const core::Error& e) {
    problem_ = e.what();
  }
}

PlaceIndex::~PlaceIndex() = default;

std::string PlaceIndex::problem() const {
  const std::lock_guard lock(mutex_);
  return problem_;
}

bool PlaceIndex::Load() const {
  const std::lock_guard lock(mutex_);
  if (tried_ || !problem_.empty()) return problem_.empty();
  tried_ = true;
  const auto start = std::chrono::steady_clock::now();
  try {
    auto loaded = std::make_unique<Loaded>();
    const std::vector<mosaic::PlaceCell> cells = store_.ReadPlaces();
    std::size_t total = 0;
    for (const auto& cell : cells) {
      if (cell.data.size() % kRecordBytes != 0) {
        core::ThrowInvalidInput(store_.file().string() + ": place index cell col " + std::to_string(cell.col) +
                                " row " + std::to_string(cell.row) + " has " + std::to_string(cell.data.size()) +
                                " bytes, not a whole number of records");
      }
      total += cell.data.size() / kRecordBytes;
    }
    loaded->descriptors.create(static_cast<int>(total), kDescriptorBytes, CV_8U);
    loaded->world_mm.reserve(total);
    loaded->angle.reserve(total);
    int row = 0;
    for (const auto& cell : cells) {
      for (std::size_t at = 0; at < cell.data.size(); at += kRecordBytes, ++row) {
        float values[3];
        std::memcpy(values, cell.data.data() + at, sizeof(values));
        loaded->world_mm.emplace_back(values[0], values[1]);
        loaded->angle.push_back(values[2]);
        std::memcpy(loaded->descriptors.ptr(row), cell.data.data() + at + sizeof(values), kDescriptorBytes);
      }
    }
    if (total == 0) core::ThrowInvalidInput(store_.file().string() + ": the place index is empty (no texture?)");
    loaded->search = std::make_unique<internal::BitSamplingLsh>(loaded->descriptors, options_.lsh_tables, options_.lsh_key_bits);
    loaded->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    loaded_ = std::move(loaded);
  } catch (const cv::Exception& e) {
    problem_ = store_.file().string() + ": cannot build the place index's search: " + e.what();
  } catch (const core::Error& e) {
    problem_ = e.what();
  }
  return problem_.empty();
}

std::int64_t PlaceIndex::features() const {
  const std::lock_guard lock(mutex_);
  return loaded_ ? static_cast<std::int64_t>(loaded_->world_mm.size()) : 0;
}

std::int64_t PlaceIndex::memory_bytes() const {
  const std::lock_guard lock(mutex_);
  if (!loaded_) return 0;
  const auto n = static_cast<std::int64_t>(loaded_->world_mm.size());
  // Records, and LSH's tables: one 4-byte index per feature per table.
  return n * static_cast<std::int64_t>(sizeof(Eigen::Vector2f) + sizeof(float) + kDescriptorBytes) +
         static_cast<std::int64_t>(loaded_->search->bytes());
}

double PlaceIndex::load_seconds() const {
  const std::lock_guard lock(mutex_);
  return loaded_ ? loaded_->seconds : 0.0;
}

Eigen::Vector2d PlaceIndex::World(const Loaded& index, int feature) {
  return index.world_mm[static_cast<std::size_t>(feature)].cast<double>();
}

PlaceLookup PlaceIndex::Lookup(const cv::Mat& frame, const camera::IdealCamera& camera) const {
  PlaceLookup result;
  if (!Load()) {
    result.problem = problem();
    return result;
  }
  const Loaded& index = *loaded_;
  const double level_mm_per_px = store_.grid().LevelMmPerPx(options_.level);
  // The frame at the index's resolution: resized pixel q is frame pixel (q + 0.5) / f - 0.5.
  const double f = camera.mm_per_px() / level_mm_per_px;
  cv::Mat small;
  cv::resize(frame, small, cv::Size(), f, f, f < 1.0 ? cv::INTER_AREA : cv::INTER_LINEAR);
  const cv::Ptr<cv::ORB> orb = Detector(options_, 4 * options_.frame_features);
  std::vector<cv::KeyPoint> corners;
  orb->detect(small, corners);
  corners = Spread(corners, cv::Rect(0, 0, small.cols, small.rows), options_.frame_features);
  cv::Mat descriptors;
  orb->compute(small, corners, descriptors);
  result.frame_features = static_cast<int>(corners.size());
  if (corners.size() < static_cast<std::size_t>(options_.min_inliers)) return result;

  // Every match votes for the camera pose it implies by itself: the yaw turning the frame
  // corner's orientation into the map corner's, the position putting the one on the other.
  struct Match {
    Eigen::Vector2d camera_mm;
    int feature;  ///< of the map
    int corner;   ///< of the frame
  };
  std::vector<Match> matches;
  struct Bin {
    std::array<std::int64_t, 3> address;
    std::vector<int> members;
  };
  std::unordered_map<std::int64_t, Bin> bins;
  const int yaw_bins = std::max(1, static_cast<int>(std::lround(360.0 / options_.bin_deg)));
  const auto key_of = [yaw_bins](std::int64_t bx, std::int64_t by, std::int64_t bt) {
    bt = ((bt % yaw_bins) + yaw_bins) % yaw_bins;
    return (bx * 73856093) ^ (by * 19349663) ^ (bt * 83492791);
  };
  for (int q = 0; q < descriptors.rows; ++q) {
    const cv::KeyPoint& corner = corners[static_cast<std::size_t>(q)];
    const Eigen::Vector2d pixel((corner.pt.x + 0.5) / f - 0.5, (corner.pt.y + 0.5) / f - 0.5);
    const Eigen::Vector2d camera_mm = camera.PixelToCamera(pixel);
    const double frame_angle = UpAngle(corner);
    for (const auto& [distance, feature] : index.search->Nearest(descriptors.ptr(q), options_.neighbours)) {
      if (distance > options_.max_hamming) continue;
      const double yaw = Wrap(index.angle[static_cast<std::size_t>(feature)] - frame_angle);
      const Eigen::Vector2d t =
          World(index, feature) - Rigid{yaw, Eigen::Vector2d::Zero()}.Apply(camera_mm);
      const std::array<std::int64_t, 3> address = {
          static_cast<std::int64_t>(std::floor(t.x() / options_.bin_mm)),
          static_cast<std::int64_t>(std::floor(t.y() / options_.bin_mm)),
          static_cast<std::int64_t>(std::floor(yaw / (2.0 * std::numbers::pi) * yaw_bins)) % yaw_bins};
      Bin& bin = bins[key_of(address[0], address[1], address[2])];
      bin.address = address;
      bin.members.push_back(static_cast<int>(matches.size()));
      matches.push_back({camera_mm, feature, q});
    }
  }
  result.matches = static_cast<int>(matches.size());

  // The best-voted bins, each with its neighbours (a pose near a bin's border votes on both
  // sides), fitted to their matches: pairs of matches propose a motion (RANSAC), the one most
  // matches agree with is fitted to them by least squares.
  std::vector<const Bin*> ranked;
  for (const auto& entry : bins) ranked.push_back(&entry.second);
  std::sort(ranked.begin(), ranked.end(), [](const Bin* a, const Bin* b) {
    return a->members.size() != b->members.size() ? a->members.size() > b->members.size() : a->address < b->address;
  });
  std::mt19937 random(12345);
  const double inlier2 = options_.inlier_mm * options_.inlier_mm;
  const auto inliers_of = [&](const Rigid& motion, const std::vector<int>& set) {
    std::vector<int> agreeing;
    for (const int m : set) {
      const Match& match = matches[static_cast<std::size_t>(m)];
      if ((motion.Apply(match.camera_mm) - World(index, match.feature)).squaredNorm() <=
          inlier2) {
        agreeing.push_back(m);
      }
    }
    return agreeing;
  };
  std::vector<PlaceCandidate> candidates;
  const std::size_t tried = std::min<std::size_t>(ranked.size(), 4 * static_cast<std::size_t>(options_.max_candidates));
  for (std::size_t r = 0; r < tried; ++r) {
    if (ranked[r]->members.size() < 2) break;
    std::vector<int> set;
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dt = -1; dt <= 1; ++dt) {
          const auto& a = ranked[r]->address;
          const auto found = bins.find(key_of(a[0] + dx, a[1] + dy, a[2] + dt));
          if (found == bins.end()) continue;
          const auto& b = found->second.address;
          if (b[0] != a[0] + dx || b[1] != a[1] + dy || b[2] != (((a[2] + dt) % yaw_bins) + yaw_bins) % yaw_bins) continue;
          set.insert(set.end(), found->second.members.begin(), found->second.members.end());
        }
      }
    }
    if (set.size() < static_cast<std::size_t>(options_.min_inliers)) continue;
    std::vector<int> best;
    std::uniform_int_distribution<std::size_t> pick(0, set.size() - 1);
    for (int iteration = 0; iteration < 64; ++iteration) {
      const Match& a = matches[static_cast<std::size_t>(set[pick(random)])];
      const Match& b = matches[static_cast<std::size_t>(set[pick(random)])];
      const Eigen::Vector2d wa = World(index, a.feature);
      const Eigen::Vector2d wb = World(index, b.feature);
      const double span = (a.camera_mm - b.camera_mm).norm();
      if (span < 8.0 || std::abs(span - (wa - wb).norm()) > 2.0 * options_.inlier_mm) continue;
      std::vector<int> agreeing = inliers_of(Fit({a.camera_mm, b.camera_mm}, {wa, wb}), set);
      if (agreeing.size() > best.size()) best = std::move(agreeing);
    }
    if (best.size() < static_cast<std::size_t>(options_.min_inliers)) continue;
    Rigid motion;
    for (int round = 0; round < 2; ++round) {
      std::vector<Eigen::Vector2d> from, to;
      for (const int m : best) {
        from.push_back(matches[static_cast<std::size_t>(m)].camera_mm);
        to.push_back(World(index, matches[static_cast<std::size_t>(m)].feature));
      }
      motion = Fit(from, to);
      best = inliers_of(motion, set);
      if (best.size() < 3) break;
    }
    // One frame corner counts once, whichever copies of the floor it matched.
    double sum2 = 0.0;
    for (const int m : best) {
      const Match& match = matches[static_cast<std::size_t>(m)];
      sum2 += (motion.Apply(match.camera_mm) - World(index, match.feature)).squaredNorm();
    }
    std::unordered_set<int> corners_agreeing;
    for (const int m : best) corners_agreeing.insert(matches[static_cast<std::size_t>(m)].corner);
    PlaceCandidate candidate;
    candidate.world_from_camera = core::Pose2(motion.t, motion.yaw);
    candidate.inliers = static_cast<int>(corners_agreeing.size());
    candidate.rms_mm = best.empty() ? 0.0 : std::sqrt(sum2 / static_cast<double>(best.size()));
    if (candidate.inliers < options_.min_inliers) continue;
    const auto same = std::find_if(candidates.begin(), candidates.end(), [&](const PlaceCandidate& c) {
      return core::Distance(c.world_from_camera, candidate.world_from_camera) < 5.0 &&
             std::abs(core::WrapAngle(c.world_from_camera.yaw_rad() - candidate.world_from_camera.yaw_rad())) < 0.05;
    });
    if (same == candidates.end()) {
      candidates.push_back(candidate);
    } else if (candidate.inliers > same->inliers) {
      *same = candidate;
    }
  }
  std::sort(candidates.begin(), candidates.end(),
            [](const PlaceCandidate& a, const PlaceCandidate& b) { return a.inliers > b.inliers; });
  if (candidates.size() > static_cast<std::size_t>(options_.max_candidates)) {
    candidates.resize(static_cast<std::size_t>(options_.max_candidates));
  }
  result.candidates = std::move(candidates);
  return result;
}

}  // namespace mosaicloc::tracking
