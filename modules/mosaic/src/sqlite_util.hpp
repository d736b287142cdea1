#pragma once
// Private helpers of the map's SQLite files (the tile store and the build checkpoint).

#include <sqlite3.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>

#include "crc32.hpp"
#include "mosaicloc/core/error.hpp"

namespace mosaicloc::mosaic::internal {

/// A prepared statement that finalizes itself. Throws core::Error (runtime) naming the file
/// and the SQL when it cannot be prepared.
class Statement {
 public:
  Statement(sqlite3* db, const char* sql, const std::filesystem::path& file) {
    if (sqlite3_prepare_v2(db, sql, -1, &statement_, nullptr) != SQLITE_OK) {
      core::ThrowRuntime(file.string() + ": SQLite cannot prepare '" + sql + "': " + sqlite3_errmsg(db));
    }
  }
  ~Statement() { sqlite3_finalize(statement_); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  sqlite3_stmt* get() const { return statement_; }

 private:
  sqlite3_stmt* statement_ = nullptr;
};

/// zlib's CRC32 of a block of bytes.
inline std::uint32_t Crc32(const void* data, std::size_t bytes) { return Crc32Update(0, data, bytes); }

}  // namespace mosaicloc::mosaic::internal
