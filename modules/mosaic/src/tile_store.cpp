#include "mosaicloc/mosaic/tile_store.hpp"

#include <sqlite3.h>

#include <charconv>
#include <chrono>
#include <cmath>
#include <ctime>
#include <cstring>
#include <limits>
#include <map>

#include "mosaicloc/core/error.hpp"
#include "png_codec.hpp"
#include "sqlite_util.hpp"

namespace mosaicloc::mosaic {
namespace {

using internal::Statement;

// A connection that finds the file locked for a moment (another connection opening it and
// recovering its write-ahead log, a checkpoint) waits this long before it reports the lock.
constexpr int kBusyTimeoutMs = 5000;

std::string FormatDouble(double value) {
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);  // shortest round trip
  return std::string(buffer, result.ptr);
}

}  // namespace

TileStore::TileStore(std::filesystem::path file, sqlite3* db, MapGrid grid)
    : file_(std::move(file)), db_(db), grid_(grid) {}

TileStore::~TileStore() {
  // Readers first: the writable connection, closing last, checkpoints the WAL into the file.
  idle_readers_.clear();
  sqlite3_close(db_);
}

void TileStore::Execute(const std::string& sql) const {
  internal::Execute(db_, sql, file_);
}

std::unique_ptr<TileStore> TileStore::Create(const std::filesystem::path& file, const MapGrid& grid) {
  std::string why;
  if (!grid.Check(&why)) core::ThrowInvalidInput(file.string() + ": " + why);
  std::error_code ec;
  if (std::filesystem::exists(file, ec)) core::ThrowInvalidInput(file.string() + ": already exists");
  sqlite3* db = nullptr;
  if (sqlite3_open_v2(file.c_str(), &db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_FULLMUTEX, nullptr) !=
      SQLITE_OK) {
    const std::string reason = internal::Why(db);
    sqlite3_close(db);
    core::ThrowRuntime(file.string() + ": cannot create the map: " + reason);
  }
  std::unique_ptr<TileStore> store(new TileStore(file, db, grid));
  sqlite3_busy_timeout(db, kBusyTimeoutMs);
  // 64 KiB pages (SQLite's largest): a 256 px tile stored as a level-0 PNG (66 KB) spans two
  // pages, where 4 KiB pages made it a chain of 17, each its own read.
  store->Execute("PRAGMA page_size=65536; PRAGMA journal_mode=WAL; PRAGMA synchronous=FULL;");
  store->Execute(
      "BEGIN;"
      "CREATE TABLE metadata (name TEXT PRIMARY KEY, value TEXT);"
      "CREATE TABLE tiles (level INTEGER, col INTEGER, row INTEGER, data BLOB, crc32 INTEGER,"
      " PRIMARY KEY (level, col, row));"
      "INSERT INTO metadata VALUES ('format_version', '" + std::to_string(kMapFormatVersion) + "'),"
      " ('mm_per_px', '" + FormatDouble(grid.mm_per_px) + "'),"
      " ('origin_x_mm', '" + FormatDouble(grid.origin_x_mm) + "'),"
      " ('origin_y_mm', '" + FormatDouble(grid.origin_y_mm) + "'),"
      " ('tile_size_px', '" + std::to_string(grid.tile_size_px) + "'),"
      " ('levels', '" + std::to_string(grid.levels) + "');"
      "COMMIT;");
  return store;
}

std::unique_ptr<TileStore> TileStore::Open(const std::filesystem::path& file, bool writable) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) core::ThrowInvalidInput(file.string() + ": no such map file");
  sqlite3* db = nullptr;
  const int flags = (writable ? SQLITE_OPEN_READWRITE : SQLITE_OPEN_READONLY) | SQLITE_OPEN_FULLMUTEX;
  if (sqlite3_open_v2(file.c_str(), &db, flags, nullptr) != SQLITE_OK) {
    const std::string reason = internal::Why(db);
    sqlite3_close(db);
    core::ThrowInvalidInput(file.string() + ": cannot open the map: " + reason);
  }
  std::unique_ptr<TileStore> store(new TileStore(file, db, MapGrid{}));
  sqlite3_busy_timeout(db, kBusyTimeoutMs);
  std::map<std::string, std::string> metadata;
  {
    sqlite3_stmt* raw = nullptr;
    if (sqlite3_prepare_v2(db, "SELECT name, value FROM metadata", -1, &raw, nullptr) != SQLITE_OK) {
      const std::string reason = internal::Why(db);
      const int code = sqlite3_errcode(db) & 0xff;
      sqlite3_finalize(raw);
      // A file that could not be read now (locked, an I/O error) is not a bad map.
      if (code == SQLITE_BUSY || code == SQLITE_LOCKED || code == SQLITE_IOERR || code == SQLITE_NOMEM) {
        core::ThrowRuntime(file.string() + ": cannot read the map: " + reason);
      }
      core::ThrowInvalidInput(file.string() + ": not a mosaicloc map (" + reason + ")");
    }
    while (sqlite3_step(raw) == SQLITE_ROW) {
      const auto* name = reinterpret_cast<const char*>(sqlite3_column_text(raw, 0));
      const auto* value = reinterpret_cast<const char*>(sqlite3_column_text(raw, 1));
      if (name && value) metadata[name] = value;
    }
    sqlite3_finalize(raw);
  }
  const auto number = [&](const char* key) {
    const auto it = metadata.find(key);
    if (it == metadata.end()) core::ThrowInvalidInput(file.string() + ": metadata key '" + key + "' is missing");
    double value = 0.0;
    const char* end = it->second.data() + it->second.size();
    const auto result = std::from_chars(it->second.data(), end, value);
    if (result.ec != std::errc() || result.ptr != end) {
      core::ThrowInvalidInput(file.string() + ": metadata key '" + key + "' is not a number: '" + it->second + "'");
    }
    return value;
  };
  const double version = number("format_version");
  if (version != kMapFormatVersion) {
    core::ThrowInvalidInput(file.string() + ": format_version " + metadata["format_version"] +
                            " is not supported (this build reads version " + std::to_string(kMapFormatVersion) + ")");
  }
  MapGrid& grid = store->grid_;
  grid.mm_per_px = number("mm_per_px");
  grid.origin_x_mm = number("origin_x_mm");
  grid.origin_y_mm = number("origin_y_mm");
  // A whole number that an int holds, before it becomes one (the grid's Check then bounds it).
  const auto integer = [&](const char* key) {
    const double value = number(key);
    if (!(std::trunc(value) == value && std::abs(value) <= std::numeric_limits<int>::max())) {
      core::ThrowInvalidInput(file.string() + ": metadata key '" + key + "' must be a whole number within " +
                              std::to_string(std::numeric_limits<int>::max()) + ": '" + metadata[key] + "'");
    }
    return static_cast<int>(value);
  };
  grid.tile_size_px = integer("tile_size_px");
  grid.levels = integer("levels");
  std::string why;
  if (!grid.Check(&why)) core::ThrowInvalidInput(file.string() + ": metadata: " + why);
  if (writable) store->Execute("PRAGMA journal_mode=WAL; PRAGMA synchronous=FULL;");
  return store;
}

void TileStore::SetPngCompression(int level) {
  if (level < 0 || level > 9) {
    core::ThrowInvalidInput(file_.string() + ": PNG compression level " + std::to_string(level) + " is not in 0-9");
  }
  png_compression_ = level;
}

std::vector<unsigned char> TileStore::Encode(const cv::Mat& pixels, int png_compression) {
  return internal::EncodeGreyPng(pixels, png_compression);
}

std::string TileStore::Decode(const std::vector<unsigned char>& png, int tile_size_px, cv::Mat& pixels) {
  return internal::DecodeGreyPng(png.data(), png.size(), tile_size_px, pixels);
}

std::uint32_t TileStore::Crc32(const std::vector<unsigned char>& data) {
  return internal::Crc32(data.data(), data.size());
}

struct TileStore::Reader {
  sqlite3* db = nullptr;
  sqlite3_stmt* select = nullptr;
};

void TileStore::ReaderDeleter::operator()(Reader* reader) const {
  sqlite3_finalize(reader->select);
  sqlite3_close(reader->db);
  delete reader;
}

TileStore::ReaderPtr TileStore::TakeReader(std::string* why) const {
  {
    const std::lock_guard lock(readers_mutex_);
    if (!idle_readers_.empty()) {
      ReaderPtr reader = std::move(idle_readers_.back());
      idle_readers_.pop_back();
      return reader;
    }
  }
  // Used by one thread at a time (the pool hands it out), so SQLite's own mutex is not needed.
  ReaderPtr reader(new Reader());
  if (sqlite3_open_v2(file_.c_str(), &reader->db, SQLITE_OPEN_READONLY | SQLITE_OPEN_NOMUTEX, nullptr) != SQLITE_OK ||
      sqlite3_prepare_v2(reader->db, "SELECT data, crc32 FROM tiles WHERE level = ? AND col = ? AND row = ?", -1,
                         &reader->select, nullptr) != SQLITE_OK) {
    *why = internal::Why(reader->db);
    return nullptr;
  }
  sqlite3_busy_timeout(reader->db, kBusyTimeoutMs);
  return reader;
}

void TileStore::GiveBack(ReaderPtr reader) const {
  sqlite3_reset(reader->select);
  sqlite3_clear_bindings(reader->select);
  const std::lock_guard lock(readers_mutex_);
  idle_readers_.push_back(std::move(reader));
}

TileStatus TileStore::Fetch(const TileKey& key,
                            const std::function<std::string(const unsigned char*, std::size_t)>& use,
                            std::string* problem) const {
  const auto corrupt = [&](const std::string& reason) {
    *problem = file_.string() + ": tile " + key.ToString() + ": " + reason;
    return TileStatus::kCorrupt;
  };
  std::string why;
  ReaderPtr reader = TakeReader(&why);
  if (!reader) return corrupt("cannot be read: " + why);
  sqlite3_stmt* select = reader->select;
  sqlite3_bind_int(select, 1, key.level);
  sqlite3_bind_int64(select, 2, key.col);
  sqlite3_bind_int64(select, 3, key.row);
  const int step = sqlite3_step(select);
  if (step == SQLITE_DONE) {
    GiveBack(std::move(reader));
    return TileStatus::kAbsent;  // unmapped
  }
  if (step != SQLITE_ROW) {
    // The connection is dropped, not pooled: whatever went wrong stays with it.
    return corrupt(std::string("cannot be read: ") + internal::Why(reader->db));
  }
  // The blob is checked and used where SQLite holds it (valid until the statement is reset),
  // not copied out first.
  const auto* blob = static_cast<const unsigned char*>(sqlite3_column_blob(select, 0));
  const auto bytes = static_cast<std::size_t>(sqlite3_column_bytes(select, 0));
  const std::int64_t stored_crc = sqlite3_column_int64(select, 1);
  std::string reason;
  if (static_cast<std::int64_t>(internal::Crc32(blob, bytes)) != stored_crc) {
    reason = "CRC32 mismatch (the tile data is damaged)";
  } else {
    reason = use(blob, bytes);
  }
  GiveBack(std::move(reader));
  if (!reason.empty()) return corrupt(reason);
  return TileStatus::kOk;
}

TileRead TileStore::Read(const TileKey& key, cv::Mat buffer) const {
  TileRead result;
  cv::Mat pixels = buffer;
  result.status = Fetch(
      key,
      [&](const unsigned char* blob, std::size_t bytes) {
        return internal::DecodeGreyPng(blob, bytes, grid_.tile_size_px, pixels);
      },
      &result.problem);
  if (result.status == TileStatus::kOk) result.pixels = pixels;
  return result;
}

EncodedTileRead TileStore::ReadEncoded(const TileKey& key) const {
  EncodedTileRead result;
  result.status = Fetch(
      key,
      [&](const unsigned char* blob, std::size_t bytes) {
        result.png.assign(blob, blob + bytes);
        return std::string();
      },
      &result.problem);
  if (result.status != TileStatus::kOk) result.png.clear();
  return result;
}

std::vector<std::vector<unsigned char>> TileStore::EncodeAll(const std::vector<TileWrite>& tiles) const {
  std::vector<std::vector<unsigned char>> encoded;
  encoded.reserve(tiles.size());
  for (const auto& tile : tiles) {
    if (tile.pixels.type() != CV_8UC1 || tile.pixels.rows != grid_.tile_size_px ||
        tile.pixels.cols != grid_.tile_size_px) {
      core::ThrowInvalidInput(file_.string() + ": tile " + tile.key.ToString() + " to write has the wrong size or type");
    }
    encoded.push_back(Encode(tile.pixels, png_compression_));
  }
  return encoded;
}

void TileStore::Insert(const std::vector<TileWrite>& tiles, const std::vector<std::vector<unsigned char>>& encoded) {
  const Statement statement(db_, "INSERT OR REPLACE INTO tiles VALUES (?, ?, ?, ?, ?)", file_);
  for (std::size_t i = 0; i < tiles.size(); ++i) {
    sqlite3_reset(statement.get());
    sqlite3_bind_int(statement.get(), 1, tiles[i].key.level);
    sqlite3_bind_int64(statement.get(), 2, tiles[i].key.col);
    sqlite3_bind_int64(statement.get(), 3, tiles[i].key.row);
    sqlite3_bind_blob(statement.get(), 4, encoded[i].data(), static_cast<int>(encoded[i].size()), SQLITE_STATIC);
    sqlite3_bind_int64(statement.get(), 5, static_cast<std::int64_t>(Crc32(encoded[i])));
    if (sqlite3_step(statement.get()) != SQLITE_DONE) {
      core::ThrowRuntime(file_.string() + ": cannot write tile " + tiles[i].key.ToString() + ": " + internal::Why(db_));
    }
  }
}

void TileStore::Write(const std::vector<TileWrite>& tiles) {
  const std::vector<std::vector<unsigned char>> encoded = EncodeAll(tiles);
  const std::lock_guard lock(mutex_);
  Execute("BEGIN IMMEDIATE;");
  try {
    Insert(tiles, encoded);
    Execute("COMMIT;");
  } catch (...) {
    sqlite3_exec(db_, "ROLLBACK;", nullptr, nullptr, nullptr);
    throw;
  }
}

namespace {

bool HasTable(sqlite3* db, const char* name);

// Now, UTC, ISO 8601 to the second.
std::string UtcNow() {
  const std::time_t now = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm utc{};
  gmtime_r(&now, &utc);
  char text[32];
  std::strftime(text, sizeof(text), "%Y-%m-%dT%H:%M:%SZ", &utc);
  return text;
}

std::string ColumnText(sqlite3_stmt* statement, int column) {
  const auto* text = reinterpret_cast<const char*>(sqlite3_column_text(statement, column));
  return text ? text : "";
}

// The history's tables (design.md section 4): a map written before them has neither, and they
// are made by the first recorded write.
constexpr const char* kHistorySchema =
    "CREATE TABLE IF NOT EXISTS updates (id INTEGER PRIMARY KEY, time TEXT NOT NULL, reason TEXT NOT NULL,"
    " tiles INTEGER NOT NULL, reverted TEXT);"
    "CREATE TABLE IF NOT EXISTS replaced (update_id INTEGER NOT NULL, level INTEGER, col INTEGER, row INTEGER,"
    " data BLOB, crc32 INTEGER, PRIMARY KEY (update_id, level, col, row));";

}  // namespace

std::int64_t TileStore::WriteRecorded(const std::vector<TileWrite>& tiles, const std::string& reason) {
  if (reason.empty()) core::ThrowInvalidInput(file_.string() + ": a recorded write needs a reason");
  const std::vector<std::vector<unsigned char>> encoded = EncodeAll(tiles);
  const std::lock_guard lock(mutex_);
  Execute("BEGIN IMMEDIATE;");
  try {
    Execute(kHistorySchema);
    std::int64_t level0 = 0;
    for (const TileWrite& tile : tiles) level0 += tile.key.level == 0 ? 1 : 0;
    {
      const Statement insert(db_, "INSERT INTO updates (time, reason, tiles) VALUES (?, ?, ?)", file_);
      const std::string now = UtcNow();
      sqlite3_bind_text(insert.get(), 1, now.c_str(), -1, SQLITE_TRANSIENT);
      sqlite3_bind_text(insert.get(), 2, reason.c_str(), -1, SQLITE_TRANSIENT);
      sqlite3_bind_int64(insert.get(), 3, level0);
      if (sqlite3_step(insert.get()) != SQLITE_DONE) {
        core::ThrowRuntime(file_.string() + ": cannot record an update: " + internal::Why(db_));
      }
    }
    const std::int64_t id = sqlite3_last_insert_rowid(db_);
    // The level-0 tiles as they are now, copied as stored (a NULL blob: absent). The pyramid
    // above is not kept: it is recomputed from level 0 when the update is undone.
    const Statement keep(db_,
                         "INSERT INTO replaced SELECT ?1, ?2, ?3, ?4,"
                         " (SELECT data FROM tiles WHERE level = ?2 AND col = ?3 AND row = ?4),"
                         " (SELECT crc32 FROM tiles WHERE level = ?2 AND col = ?3 AND row = ?4)",
                         file_);
    for (const TileWrite& tile : tiles) {
      if (tile.key.level != 0) continue;
      sqlite3_reset(keep.get());
      sqlite3_bind_int64(keep.get(), 1, id);
      sqlite3_bind_int(keep.get(), 2, 0);
      sqlite3_bind_int64(keep.get(), 3, tile.key.col);
      sqlite3_bind_int64(keep.get(), 4, tile.key.row);
      if (sqlite3_step(keep.get()) != SQLITE_DONE) {
        core::ThrowRuntime(file_.string() + ": cannot keep tile " + tile.key.ToString() + ": " + internal::Why(db_));
      }
    }
    Insert(tiles, encoded);
    Execute("COMMIT;");
    return id;
  } catch (...) {
    sqlite3_exec(db_, "ROLLBACK;", nullptr, nullptr, nullptr);
    throw;
  }
}

std::vector<MapUpdate> TileStore::History() const {
  const std::lock_guard lock(mutex_);
  std::vector<MapUpdate> updates;
  if (!HasTable(db_, "updates")) return updates;
  const Statement statement(db_, "SELECT id, time, reason, tiles, reverted FROM updates ORDER BY id", file_);
  while (sqlite3_step(statement.get()) == SQLITE_ROW) {
    updates.push_back(MapUpdate{sqlite3_column_int64(statement.get(), 0), ColumnText(statement.get(), 1),
                                ColumnText(statement.get(), 2), sqlite3_column_int64(statement.get(), 3),
                                ColumnText(statement.get(), 4)});
  }
  return updates;
}

std::vector<ReplacedTile> TileStore::Replaced(std::int64_t id) const {
  const std::lock_guard lock(mutex_);
  const std::string name = file_.string() + ": update " + std::to_string(id);
  if (!HasTable(db_, "updates")) core::ThrowInvalidInput(name + ": the map has no recorded updates");
  {
    const Statement exists(db_, "SELECT 1 FROM updates WHERE id = ?", file_);
    sqlite3_bind_int64(exists.get(), 1, id);
    if (sqlite3_step(exists.get()) != SQLITE_ROW) core::ThrowInvalidInput(name + ": no such update");
  }
  const Statement statement(db_, "SELECT level, col, row, data, crc32 FROM replaced WHERE update_id = ? ORDER BY row, col",
                            file_);
  sqlite3_bind_int64(statement.get(), 1, id);
  std::vector<ReplacedTile> tiles;
  while (sqlite3_step(statement.get()) == SQLITE_ROW) {
    ReplacedTile tile;
    tile.key = TileKey{sqlite3_column_int(statement.get(), 0), sqlite3_column_int64(statement.get(), 1),
                       sqlite3_column_int64(statement.get(), 2)};
    if (sqlite3_column_type(statement.get(), 3) != SQLITE_NULL) {
      const auto* blob = static_cast<const unsigned char*>(sqlite3_column_blob(statement.get(), 3));
      const std::vector<unsigned char> png(blob, blob + sqlite3_column_bytes(statement.get(), 3));
      const auto crc = static_cast<std::uint32_t>(sqlite3_column_int64(statement.get(), 4));
      if (Crc32(png) != crc) core::ThrowInvalidInput(name + ": kept tile " + tile.key.ToString() + ": CRC mismatch");
      cv::Mat pixels;
      const std::string problem = Decode(png, grid_.tile_size_px, pixels);
      if (!problem.empty()) core::ThrowInvalidInput(name + ": kept tile " + tile.key.ToString() + ": " + problem);
      tile.pixels = pixels;
    }
    tiles.push_back(std::move(tile));
  }
  return tiles;
}

std::vector<std::pair<std::int64_t, TileKey>> TileStore::UpdatedTiles() const {
  const std::lock_guard lock(mutex_);
  std::vector<std::pair<std::int64_t, TileKey>> tiles;
  if (!HasTable(db_, "replaced")) return tiles;
  const Statement statement(db_, "SELECT update_id, level, col, row FROM replaced ORDER BY update_id, row, col", file_);
  while (sqlite3_step(statement.get()) == SQLITE_ROW) {
    tiles.emplace_back(sqlite3_column_int64(statement.get(), 0),
                       TileKey{sqlite3_column_int(statement.get(), 1), sqlite3_column_int64(statement.get(), 2),
                               sqlite3_column_int64(statement.get(), 3)});
  }
  return tiles;
}

std::int64_t TileStore::DataVersion() const {
  const std::lock_guard lock(mutex_);
  const Statement statement(db_, "PRAGMA data_version", file_);
  return sqlite3_step(statement.get()) == SQLITE_ROW ? sqlite3_column_int64(statement.get(), 0) : 0;
}

void TileStore::WriteRevert(std::int64_t id, const std::vector<TileWrite>& tiles, const std::vector<TileKey>& removed) {
  const std::vector<std::vector<unsigned char>> encoded = EncodeAll(tiles);
  const std::lock_guard lock(mutex_);
  Execute("BEGIN IMMEDIATE;");
  try {
    {
      const Statement mark(db_, "UPDATE updates SET reverted = ? WHERE id = ? AND reverted IS NULL", file_);
      const std::string now = UtcNow();
      sqlite3_bind_text(mark.get(), 1, now.c_str(), -1, SQLITE_TRANSIENT);
      sqlite3_bind_int64(mark.get(), 2, id);
      if (sqlite3_step(mark.get()) != SQLITE_DONE || sqlite3_changes(db_) != 1) {
        core::ThrowInvalidInput(file_.string() + ": update " + std::to_string(id) + " is not in force");
      }
    }
    Insert(tiles, encoded);
    const Statement remove(db_, "DELETE FROM tiles WHERE level = ? AND col = ? AND row = ?", file_);
    for (const TileKey& key : removed) {
      sqlite3_reset(remove.get());
      sqlite3_bind_int(remove.get(), 1, key.level);
      sqlite3_bind_int64(remove.get(), 2, key.col);
      sqlite3_bind_int64(remove.get(), 3, key.row);
      if (sqlite3_step(remove.get()) != SQLITE_DONE) {
        core::ThrowRuntime(file_.string() + ": cannot remove tile " + key.ToString() + ": " + internal::Why(db_));
      }
    }
    Execute("COMMIT;");
  } catch (...) {
    sqlite3_exec(db_, "ROLLBACK;", nullptr, nullptr, nullptr);
    throw;
  }
}

namespace {

// Metadata keys of the place index; the table `places` holds its cells.
constexpr const char* kPlacesKeys[] = {"places_format_version", "places_method", "places_level"};
constexpr const char* kRepeatTestKeys[] = {"places_repeat_test_views", "places_repeat_test_own",
                                           "places_repeat_test_elsewhere"};

bool HasTable(sqlite3* db, const char* name) {
  sqlite3_stmt* raw = nullptr;
  bool found = false;
  if (sqlite3_prepare_v2(db, "SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = ?", -1, &raw, nullptr) ==
      SQLITE_OK) {
    sqlite3_bind_text(raw, 1, name, -1, SQLITE_STATIC);
    found = sqlite3_step(raw) == SQLITE_ROW;
  }
  sqlite3_finalize(raw);
  return found;
}

bool HasPlacesTable(sqlite3* db) { return HasTable(db, "places"); }

// A quality cell's CRC32: over its address and values as stored (little-endian on every
// machine the map is written on; the check only has to agree with itself).
std::uint32_t QualityCrc(const QualityCell& cell) {
  unsigned char bytes[2 * sizeof(std::int64_t) + 3 * sizeof(float)];
  std::memcpy(bytes, &cell.col, sizeof(std::int64_t));
  std::memcpy(bytes + 8, &cell.row, sizeof(std::int64_t));
  std::memcpy(bytes + 16, &cell.mapped, sizeof(float));
  std::memcpy(bytes + 20, &cell.texture, sizeof(float));
  std::memcpy(bytes + 24, &cell.ambiguity, sizeof(float));
  return internal::Crc32(bytes, sizeof(bytes));
}

}  // namespace

std::optional<PlaceIndexInfo> TileStore::Places() const {
  const std::lock_guard lock(mutex_);
  if (!HasPlacesTable(db_)) return std::nullopt;
  std::map<std::string, std::string> values;
  {
    const Statement statement(db_, "SELECT name, value FROM metadata WHERE name LIKE 'places_%'", file_);
    while (sqlite3_step(statement.get()) == SQLITE_ROW) {
      const auto* name = reinterpret_cast<const char*>(sqlite3_column_text(statement.get(), 0));
      const auto* value = reinterpret_cast<const char*>(sqlite3_column_text(statement.get(), 1));
      if (name && value) values[name] = value;
    }
  }
  PlaceIndexInfo info;
  const auto integer = [&](const char* key) {
    const auto it = values.find(key);
    if (it == values.end()) core::ThrowInvalidInput(file_.string() + ": metadata key '" + key + "' is missing");
    int value = 0;
    const char* end = it->second.data() + it->second.size();
    const auto result = std::from_chars(it->second.data(), end, value);
    if (result.ec != std::errc() || result.ptr != end) {
      core::ThrowInvalidInput(file_.string() + ": metadata key '" + key + "' is not an integer: '" + it->second + "'");
    }
    return value;
  };
  info.format_version = integer(kPlacesKeys[0]);
  info.level = integer(kPlacesKeys[2]);
  const auto method = values.find(kPlacesKeys[1]);
  if (method == values.end()) core::ThrowInvalidInput(file_.string() + ": metadata key 'places_method' is missing");
  info.method = method->second;
  const auto optional_count = [&](const char* key) -> std::int64_t {
    const auto it = values.find(key);
    if (it == values.end()) return -1;
    std::int64_t value = 0;
    const char* end = it->second.data() + it->second.size();
    const auto result = std::from_chars(it->second.data(), end, value);
    if (result.ec != std::errc() || result.ptr != end || value < 0) {
      core::ThrowInvalidInput(file_.string() + ": metadata key '" + key + "' is not a count: '" + it->second + "'");
    }
    return value;
  };
  info.repeat_test_views = optional_count(kRepeatTestKeys[0]);
  info.repeat_test_own = optional_count(kRepeatTestKeys[1]);
  info.repeat_test_elsewhere = optional_count(kRepeatTestKeys[2]);
  const Statement count(db_, "SELECT COUNT(*), COALESCE(SUM(LENGTH(data)), 0) FROM places", file_);
  if (sqlite3_step(count.get()) == SQLITE_ROW) {
    info.cells = sqlite3_column_int64(count.get(), 0);
    info.bytes = sqlite3_column_int64(count.get(), 1);
  }
  return info;
}

void TileStore::WritePlaceRepeatTest(std::int64_t views, std::int64_t own, std::int64_t elsewhere) {
  const std::lock_guard lock(mutex_);
  Execute("BEGIN IMMEDIATE;");
  try {
    const Statement meta(db_, "INSERT OR REPLACE INTO metadata VALUES (?, ?)", file_);
    const std::int64_t values[] = {views, own, elsewhere};
    for (int i = 0; i < 3; ++i) {
      sqlite3_reset(meta.get());
      sqlite3_bind_text(meta.get(), 1, kRepeatTestKeys[i], -1, SQLITE_STATIC);
      const std::string value = std::to_string(values[i]);
      sqlite3_bind_text(meta.get(), 2, value.c_str(), -1, SQLITE_TRANSIENT);
      if (sqlite3_step(meta.get()) != SQLITE_DONE) {
        core::ThrowRuntime(file_.string() + ": cannot write the floor's self-test: " + internal::Why(db_));
      }
    }
    Execute("COMMIT;");
  } catch (...) {
    sqlite3_exec(db_, "ROLLBACK;", nullptr, nullptr, nullptr);
    throw;
  }
}

std::vector<PlaceCell> TileStore::ReadPlaces() const {
  const std::lock_guard lock(mutex_);
  if (!HasPlacesTable(db_)) core::ThrowInvalidInput(file_.string() + ": the map has no place index");
  const Statement statement(db_, "SELECT col, row, data, crc32 FROM places ORDER BY row, col", file_);
  std::vector<PlaceCell> cells;
  int step = SQLITE_ROW;
  while ((step = sqlite3_step(statement.get())) == SQLITE_ROW) {
    PlaceCell cell;
    cell.col = sqlite3_column_int64(statement.get(), 0);
    cell.row = sqlite3_column_int64(statement.get(), 1);
    const auto* blob = static_cast<const unsigned char*>(sqlite3_column_blob(statement.get(), 2));
    const auto bytes = static_cast<std::size_t>(sqlite3_column_bytes(statement.get(), 2));
    if (blob != nullptr) cell.data.assign(blob, blob + bytes);
    if (static_cast<std::int64_t>(Crc32(cell.data)) != sqlite3_column_int64(statement.get(), 3)) {
      core::ThrowInvalidInput(file_.string() + ": place index cell col " + std::to_string(cell.col) + " row " +
                              std::to_string(cell.row) + ": CRC32 mismatch (the index is damaged: rebuild it with "
                              "`mosaicloc map index`)");
    }
    cells.push_back(std::move(cell));
  }
  if (step != SQLITE_DONE) core::ThrowRuntime(file_.string() + ": cannot read the place index: " + internal::Why(db_));
  return cells;
}

void TileStore::WritePlaces(const PlaceIndexInfo& info, const std::vector<PlaceCell>& cells) {
  const std::lock_guard lock(mutex_);
  Execute("BEGIN IMMEDIATE;");
  try {
    Execute(
        "DROP TABLE IF EXISTS places;"
        "DELETE FROM metadata WHERE name LIKE 'places_repeat_test_%';"
        "CREATE TABLE places (col INTEGER, row INTEGER, data BLOB, crc32 INTEGER, PRIMARY KEY (col, row));");
    {
      const Statement meta(db_, "INSERT OR REPLACE INTO metadata VALUES (?, ?)", file_);
      const std::string values[] = {std::to_string(info.format_version), info.method, std::to_string(info.level)};
      for (int i = 0; i < 3; ++i) {
        sqlite3_reset(meta.get());
        sqlite3_bind_text(meta.get(), 1, kPlacesKeys[i], -1, SQLITE_STATIC);
        sqlite3_bind_text(meta.get(), 2, values[i].c_str(), -1, SQLITE_TRANSIENT);
        if (sqlite3_step(meta.get()) != SQLITE_DONE) {
          core::ThrowRuntime(file_.string() + ": cannot write the place index's metadata: " + internal::Why(db_));
        }
      }
    }
    const Statement statement(db_, "INSERT INTO places VALUES (?, ?, ?, ?)", file_);
    for (const PlaceCell& cell : cells) {
      sqlite3_reset(statement.get());
      sqlite3_bind_int64(statement.get(), 1, cell.col);
      sqlite3_bind_int64(statement.get(), 2, cell.row);
      sqlite3_bind_blob(statement.get(), 3, cell.data.data(), static_cast<int>(cell.data.size()), SQLITE_STATIC);
      sqlite3_bind_int64(statement.get(), 4, static_cast<std::int64_t>(Crc32(cell.data)));
      if (sqlite3_step(statement.get()) != SQLITE_DONE) {
        core::ThrowRuntime(file_.string() + ": cannot write place index cell col " + std::to_string(cell.col) +
                           " row " + std::to_string(cell.row) + ": " + internal::Why(db_));
      }
    }
    Execute("COMMIT;");
  } catch (...) {
    sqlite3_exec(db_, "ROLLBACK;", nullptr, nullptr, nullptr);
    throw;
  }
}

std::optional<QualityInfo> TileStore::Quality() const {
  const std::lock_guard lock(mutex_);
  if (!HasTable(db_, "quality")) return std::nullopt;
  QualityInfo info;
  const Statement meta(db_, "SELECT value FROM metadata WHERE name = 'quality_level'", file_);
  if (sqlite3_step(meta.get()) != SQLITE_ROW) core::ThrowInvalidInput(file_.string() + ": metadata key 'quality_level' is missing");
  const std::string level = reinterpret_cast<const char*>(sqlite3_column_text(meta.get(), 0));
  const auto result = std::from_chars(level.data(), level.data() + level.size(), info.level);
  if (result.ec != std::errc() || result.ptr != level.data() + level.size() || info.level < 0 || info.level >= grid_.levels) {
    core::ThrowInvalidInput(file_.string() + ": metadata key 'quality_level' is not a level of the map: '" + level + "'");
  }
  const Statement count(db_, "SELECT COUNT(*) FROM quality", file_);
  if (sqlite3_step(count.get()) == SQLITE_ROW) info.cells = sqlite3_column_int64(count.get(), 0);
  return info;
}

std::vector<QualityCell> TileStore::ReadQuality() const {
  const std::lock_guard lock(mutex_);
  if (!HasTable(db_, "quality")) core::ThrowInvalidInput(file_.string() + ": the map has no quality layer");
  const Statement statement(db_, "SELECT col, row, mapped, texture, ambiguity, crc32 FROM quality ORDER BY row, col", file_);
  std::vector<QualityCell> cells;
  int step = SQLITE_ROW;
  while ((step = sqlite3_step(statement.get())) == SQLITE_ROW) {
    QualityCell cell;
    cell.col = sqlite3_column_int64(statement.get(), 0);
    cell.row = sqlite3_column_int64(statement.get(), 1);
    cell.mapped = static_cast<float>(sqlite3_column_double(statement.get(), 2));
    cell.texture = static_cast<float>(sqlite3_column_double(statement.get(), 3));
    cell.ambiguity = static_cast<float>(sqlite3_column_double(statement.get(), 4));
    if (static_cast<std::int64_t>(QualityCrc(cell)) != sqlite3_column_int64(statement.get(), 5)) {
      core::ThrowInvalidInput(file_.string() + ": quality cell col " + std::to_string(cell.col) + " row " +
                              std::to_string(cell.row) +
                              ": CRC32 mismatch (the layer is damaged: rebuild it with `mosaicloc map quality MAP "
                              "--out DIR --rebuild`)");
    }
    cells.push_back(cell);
  }
  if (step != SQLITE_DONE) core::ThrowRuntime(file_.string() + ": cannot read the quality layer: " + internal::Why(db_));
  return cells;
}

void TileStore::WriteQuality(int level, const std::vector<QualityCell>& cells) {
  if (level < 0 || level >= grid_.levels) {
    core::ThrowInvalidInput(file_.string() + ": quality level " + std::to_string(level) + " is not a level of the map");
  }
  const std::lock_guard lock(mutex_);
  Execute("BEGIN IMMEDIATE;");
  try {
    Execute(
        "DROP TABLE IF EXISTS quality;"
        "CREATE TABLE quality (col INTEGER, row INTEGER, mapped REAL, texture REAL, ambiguity REAL, crc32 INTEGER,"
        " PRIMARY KEY (col, row));");
    {
      const Statement meta(db_, "INSERT OR REPLACE INTO metadata VALUES ('quality_level', ?)", file_);
      const std::string value = std::to_string(level);
      sqlite3_bind_text(meta.get(), 1, value.c_str(), -1, SQLITE_TRANSIENT);
      if (sqlite3_step(meta.get()) != SQLITE_DONE) {
        core::ThrowRuntime(file_.string() + ": cannot write the quality layer's metadata: " + internal::Why(db_));
      }
    }
    const Statement statement(db_, "INSERT INTO quality VALUES (?, ?, ?, ?, ?, ?)", file_);
    for (const QualityCell& cell : cells) {
      sqlite3_reset(statement.get());
      sqlite3_bind_int64(statement.get(), 1, cell.col);
      sqlite3_bind_int64(statement.get(), 2, cell.row);
      sqlite3_bind_double(statement.get(), 3, cell.mapped);
      sqlite3_bind_double(statement.get(), 4, cell.texture);
      sqlite3_bind_double(statement.get(), 5, cell.ambiguity);
      sqlite3_bind_int64(statement.get(), 6, static_cast<std::int64_t>(QualityCrc(cell)));
      if (sqlite3_step(statement.get()) != SQLITE_DONE) {
        core::ThrowRuntime(file_.string() + ": cannot write quality cell col " + std::to_string(cell.col) + " row " +
                           std::to_string(cell.row) + ": " + internal::Why(db_));
      }
    }
    Execute("COMMIT;");
  } catch (...) {
    sqlite3_exec(db_, "ROLLBACK;", nullptr, nullptr, nullptr);
    throw;
  }
}

void TileStore::Checkpoint() {
  {
    // This store's own idle readers hold no snapshot, but close them all the same: the
    // file is about to be handed on.
    const std::lock_guard lock(readers_mutex_);
    idle_readers_.clear();
  }
  const std::lock_guard lock(mutex_);
  int log_frames = -1, checkpointed = -1;
  const int rc = sqlite3_wal_checkpoint_v2(db_, nullptr, SQLITE_CHECKPOINT_TRUNCATE, &log_frames, &checkpointed);
  if (rc != SQLITE_OK) {
    core::ThrowRuntime(file_.string() + ": cannot checkpoint the write-ahead log into the map: " + internal::Why(db_));
  }
  // A finished map in WAL mode makes every reader leave a log and a shared-memory file beside
  // it (a read-only connection cannot remove them); the next writable Open turns WAL on again.
  Execute("PRAGMA journal_mode=DELETE;");
}

std::vector<TileKey> TileStore::List(int level) const {
  const std::lock_guard lock(mutex_);
  const Statement statement(db_,
                            level < 0 ? "SELECT level, col, row FROM tiles ORDER BY level, row, col"
                                      : "SELECT level, col, row FROM tiles WHERE level = ? ORDER BY level, row, col",
                            file_);
  if (level >= 0) sqlite3_bind_int(statement.get(), 1, level);
  std::vector<TileKey> keys;
  while (sqlite3_step(statement.get()) == SQLITE_ROW) {
    keys.push_back({sqlite3_column_int(statement.get(), 0), sqlite3_column_int64(statement.get(), 1),
                    sqlite3_column_int64(statement.get(), 2)});
  }
  return keys;
}

std::int64_t TileStore::Count(int level) const {
  const std::lock_guard lock(mutex_);
  const Statement statement(db_, level < 0 ? "SELECT COUNT(*) FROM tiles" : "SELECT COUNT(*) FROM tiles WHERE level = ?",
                            file_);
  if (level >= 0) sqlite3_bind_int(statement.get(), 1, level);
  return sqlite3_step(statement.get()) == SQLITE_ROW ? sqlite3_column_int64(statement.get(), 0) : 0;
}

}  // namespace mosaicloc::mosaic
