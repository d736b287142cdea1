#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <string>

#include "mosaicloc/mosaic/builder.hpp"

struct sqlite3;

namespace mosaicloc::mosaic {

/// The progress of a map build, saved so that a build killed part way can resume: one
/// SQLite file (WAL) holding the builder's float accumulators exactly, how many input frames
/// they contain, and the build's identity (its inputs and settings, as the caller names
/// them). Each Save is one transaction, so after a crash the file holds the accumulators of
/// one consistent moment. Not a map: TileStore::Open rejects it (it has no metadata table).
class BuildCheckpoint {
 public:
  /// Starts a new checkpoint file (removing any old one and its WAL) for a build of
  /// `identity`. Throws core::Error naming the file if it cannot be created.
  static std::unique_ptr<BuildCheckpoint> Create(const std::filesystem::path& file,
                                                 const std::map<std::string, std::string>& identity);
  /// Opens an existing checkpoint. Throws core::Error (invalid input) naming the file and
  /// the first setting that differs when it was made for another build, or when it is not a
  /// checkpoint.
  static std::unique_ptr<BuildCheckpoint> Open(const std::filesystem::path& file,
                                               const std::map<std::string, std::string>& identity);
  ~BuildCheckpoint();
  BuildCheckpoint(const BuildCheckpoint&) = delete;
  BuildCheckpoint& operator=(const BuildCheckpoint&) = delete;

  /// Input frames the saved accumulators contain (0 for a new file).
  std::int64_t frames_done() const { return frames_done_; }
  /// Counters the caller keeps with the progress (e.g. frames without a pose); 0 if unset.
  std::int64_t counter(const std::string& name) const;

  /// Saves the tiles the builder changed since the last Save, `frames_done` and the
  /// counters, in one transaction. Throws core::Error on failure.
  void Save(MapBuilder& builder, std::int64_t frames_done, const std::map<std::string, std::int64_t>& counters);
  /// Loads the saved accumulators into a builder made with the same grid and blend. A tile
  /// whose CRC does not match throws core::Error naming the tile and the file.
  void Restore(MapBuilder& builder) const;

  /// Removes a checkpoint file and its WAL and shared-memory files.
  static void Remove(const std::filesystem::path& file);

 private:
  BuildCheckpoint(std::filesystem::path file, sqlite3* db);
  void Execute(const std::string& sql) const;

  std::filesystem::path file_;
  sqlite3* db_ = nullptr;
  std::int64_t frames_done_ = 0;
  std::int64_t frames_painted_ = 0;  ///< MapBuilder::frames() of the saved accumulators
  std::map<std::string, std::int64_t> counters_;
};

}  // namespace mosaicloc::mosaic
