#include "mosaicloc/mosaic/build_checkpoint.hpp"

#include <sqlite3.h>

#include <charconv>
#include <cstring>

#include "mosaicloc/core/error.hpp"
#include "sqlite_util.hpp"

namespace mosaicloc::mosaic {
namespace {

using internal::Crc32;
using internal::Statement;

constexpr const char* kFramesDone = "frames_done";
constexpr const char* kFramesPainted = "frames_painted";
constexpr const char* kCounterPrefix = "counter.";
constexpr const char* kIdentityPrefix = "identity.";

}  // namespace

BuildCheckpoint::BuildCheckpoint(std::filesystem::path file, sqlite3* db) : file_(std::move(file)), db_(db) {}

BuildCheckpoint::~BuildCheckpoint() { sqlite3_close(db_); }

void BuildCheckpoint::Execute(const std::string& sql) const {
  internal::Execute(db_, sql, file_);
}

void BuildCheckpoint::Remove(const std::filesystem::path& file) {
  std::error_code ec;
  for (const char* suffix : {"", "-wal", "-shm"}) std::filesystem::remove(file.string() + suffix, ec);
}

std::unique_ptr<BuildCheckpoint> BuildCheckpoint::Create(const std::filesystem::path& file,
                                                         const std::map<std::string, std::string>& identity) {
  Remove(file);
  sqlite3* db = nullptr;
  if (sqlite3_open_v2(file.c_str(), &db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_FULLMUTEX, nullptr) !=
      SQLITE_OK) {
    const std::string reason = internal::Why(db);
    sqlite3_close(db);
    core::ThrowRuntime(file.string() + ": cannot create the build checkpoint: " + reason);
  }
  std::unique_ptr<BuildCheckpoint> checkpoint(new BuildCheckpoint(file, db));
  // WAL with synchronous=NORMAL: a killed process loses nothing committed, a power cut at
  // worst the last saves; the file stays consistent either way.
  checkpoint->Execute("PRAGMA journal_mode=WAL; PRAGMA synchronous=NORMAL;");
  checkpoint->Execute(
      "BEGIN;"
      "CREATE TABLE build (name TEXT PRIMARY KEY, value TEXT);"
      "CREATE TABLE accumulators (col INTEGER, row INTEGER, data BLOB, crc32 INTEGER, PRIMARY KEY (col, row));"
      "COMMIT;");
  checkpoint->Execute("BEGIN;");
  {
    const Statement insert(db, "INSERT INTO build VALUES (?, ?)", file);
    const auto put = [&](const std::string& name, const std::string& value) {
      sqlite3_reset(insert.get());
      sqlite3_bind_text(insert.get(), 1, name.c_str(), -1, SQLITE_TRANSIENT);
      sqlite3_bind_text(insert.get(), 2, value.c_str(), -1, SQLITE_TRANSIENT);
      if (sqlite3_step(insert.get()) != SQLITE_DONE) {
        core::ThrowRuntime(file.string() + ": cannot write the build checkpoint: " + internal::Why(db));
      }
    };
    for (const auto& [name, value] : identity) put(kIdentityPrefix + name, value);
    put(kFramesDone, "0");
    put(kFramesPainted, "0");
  }
  checkpoint->Execute("COMMIT;");
  return checkpoint;
}

std::unique_ptr<BuildCheckpoint> BuildCheckpoint::Open(const std::filesystem::path& file,
                                                       const std::map<std::string, std::string>& identity) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) core::ThrowInvalidInput(file.string() + ": no build checkpoint");
  sqlite3* db = nullptr;
  if (sqlite3_open_v2(file.c_str(), &db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_FULLMUTEX, nullptr) != SQLITE_OK) {
    const std::string reason = internal::Why(db);
    sqlite3_close(db);
    core::ThrowInvalidInput(file.string() + ": cannot open the build checkpoint: " + reason);
  }
  std::unique_ptr<BuildCheckpoint> checkpoint(new BuildCheckpoint(file, db));
  std::map<std::string, std::string> stored;
  {
    sqlite3_stmt* raw = nullptr;
    if (sqlite3_prepare_v2(db, "SELECT name, value FROM build", -1, &raw, nullptr) != SQLITE_OK) {
      const std::string reason = internal::Why(db);
      sqlite3_finalize(raw);
      core::ThrowInvalidInput(file.string() + ": not a build checkpoint (" + reason + "); remove it to build afresh");
    }
    while (sqlite3_step(raw) == SQLITE_ROW) {
      const auto* name = reinterpret_cast<const char*>(sqlite3_column_text(raw, 0));
      const auto* value = reinterpret_cast<const char*>(sqlite3_column_text(raw, 1));
      if (name && value) stored[name] = value;
    }
    sqlite3_finalize(raw);
  }
  for (const auto& [name, value] : identity) {
    const auto it = stored.find(kIdentityPrefix + name);
    const std::string was = it == stored.end() ? "(none)" : it->second;
    if (was != value) {
      core::ThrowInvalidInput(file.string() + ": made by a build with " + name + " '" + was + "', not '" + value +
                              "': rerun with the same arguments, or without --resume to start again");
    }
  }
  for (const auto& [name, value] : stored) {
    if (name.rfind(kIdentityPrefix, 0) == 0 && identity.count(name.substr(std::strlen(kIdentityPrefix))) == 0) {
      core::ThrowInvalidInput(file.string() + ": made by a build with setting '" +
                              name.substr(std::strlen(kIdentityPrefix)) + "' this one does not have");
    }
    std::int64_t number = 0;
    const char* end = value.data() + value.size();
    const bool numeric = std::from_chars(value.data(), end, number).ptr == end;
    if (name == kFramesDone) {
      if (!numeric || number < 0) core::ThrowInvalidInput(file.string() + ": frames_done is not a count: '" + value + "'");
      checkpoint->frames_done_ = number;
    } else if (name == kFramesPainted) {
      if (!numeric || number < 0) core::ThrowInvalidInput(file.string() + ": frames_painted is not a count: '" + value + "'");
      checkpoint->frames_painted_ = number;
    } else if (name.rfind(kCounterPrefix, 0) == 0 && numeric) {
      checkpoint->counters_[name.substr(std::strlen(kCounterPrefix))] = number;
    }
  }
  checkpoint->Execute("PRAGMA journal_mode=WAL; PRAGMA synchronous=NORMAL;");
  return checkpoint;
}

std::int64_t BuildCheckpoint::counter(const std::string& name) const {
  const auto it = counters_.find(name);
  return it == counters_.end() ? 0 : it->second;
}

void BuildCheckpoint::Save(MapBuilder& builder, std::int64_t frames_done,
                           const std::map<std::string, std::int64_t>& counters) {
  Execute("BEGIN IMMEDIATE;");
  try {
    {
      const Statement tile(db_, "INSERT OR REPLACE INTO accumulators VALUES (?, ?, ?, ?)", file_);
      for (const TileKey& key : builder.changed_) {
        const cv::Mat& accumulator = builder.accumulators_.at(key);
        CV_Assert(accumulator.isContinuous());
        const std::size_t bytes = accumulator.total() * accumulator.elemSize();
        sqlite3_reset(tile.get());
        sqlite3_bind_int64(tile.get(), 1, key.col);
        sqlite3_bind_int64(tile.get(), 2, key.row);
        sqlite3_bind_blob(tile.get(), 3, accumulator.data, static_cast<int>(bytes), SQLITE_STATIC);
        sqlite3_bind_int64(tile.get(), 4, static_cast<std::int64_t>(Crc32(accumulator.data, bytes)));
        if (sqlite3_step(tile.get()) != SQLITE_DONE) {
          core::ThrowRuntime(file_.string() + ": cannot save tile " + key.ToString() + ": " + internal::Why(db_));
        }
      }
      const Statement value(db_, "INSERT OR REPLACE INTO build VALUES (?, ?)", file_);
      const auto put = [&](const std::string& name, std::int64_t number) {
        const std::string text = std::to_string(number);
        sqlite3_reset(value.get());
        sqlite3_bind_text(value.get(), 1, name.c_str(), -1, SQLITE_TRANSIENT);
        sqlite3_bind_text(value.get(), 2, text.c_str(), -1, SQLITE_TRANSIENT);
        if (sqlite3_step(value.get()) != SQLITE_DONE) {
          core::ThrowRuntime(file_.string() + ": cannot save the build progress: " + internal::Why(db_));
        }
      };
      put(kFramesDone, frames_done);
      put(kFramesPainted, builder.frames_);
      for (const auto& [name, number] : counters) put(kCounterPrefix + name, number);
    }
    Execute("COMMIT;");
  } catch (...) {
    sqlite3_exec(db_, "ROLLBACK;", nullptr, nullptr, nullptr);
    throw;
  }
  builder.changed_.clear();
  frames_done_ = frames_done;
  frames_painted_ = builder.frames_;
  for (const auto& [name, number] : counters) counters_[name] = number;
}

void BuildCheckpoint::Restore(MapBuilder& builder) const {
  const int t = builder.grid_.tile_size_px;
  const std::size_t bytes = static_cast<std::size_t>(t) * static_cast<std::size_t>(t) * 2 * sizeof(float);
  const Statement statement(db_, "SELECT col, row, data, crc32 FROM accumulators", file_);
  int step = SQLITE_ROW;
  while ((step = sqlite3_step(statement.get())) == SQLITE_ROW) {
    const TileKey key{0, sqlite3_column_int64(statement.get(), 0), sqlite3_column_int64(statement.get(), 1)};
    const void* blob = sqlite3_column_blob(statement.get(), 2);
    const auto size = static_cast<std::size_t>(sqlite3_column_bytes(statement.get(), 2));
    if (size != bytes || static_cast<std::int64_t>(Crc32(blob, size)) != sqlite3_column_int64(statement.get(), 3)) {
      core::ThrowInvalidInput(file_.string() + ": saved tile " + key.ToString() +
                              " is damaged (size or CRC32); remove the checkpoint to build afresh");
    }
    cv::Mat accumulator(t, t, CV_32FC2);
    std::memcpy(accumulator.data, blob, bytes);
    builder.accumulators_[key] = accumulator;
  }
  if (step != SQLITE_DONE) core::ThrowRuntime(file_.string() + ": cannot read the build checkpoint: " + internal::Why(db_));
  builder.frames_ = frames_painted_;
  builder.changed_.clear();
}

}  // namespace mosaicloc::mosaic
