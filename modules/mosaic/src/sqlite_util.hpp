#pragma once
// Private helpers of the map's SQLite files (the tile store and the build checkpoint).

#include <sqlite3.h>

#include <cerrno>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>

#include "crc32.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/core/file.hpp"

namespace mosaicloc::mosaic::internal {

/// SQLite's message for the last failure on `db`, with what it means for the user: the
/// operating system's reason where a read or write failed (a full disk, a file not allowed to
/// grow, no permission) and another process's write lock where the file was busy.
inline std::string Why(sqlite3* db) {
  // Some failed writes (a WAL checkpoint's into the database file) leave SQLite without the
  // system's error number; the C library's, read before anything else, still says why.
  const int c_errno = errno;
  if (db == nullptr) return "out of memory";
  std::string why = sqlite3_errmsg(db);
  const int code = sqlite3_errcode(db) & 0xff;
  int system = sqlite3_system_errno(db);
  if (system == 0 && code == SQLITE_IOERR && (c_errno == ENOSPC || c_errno == EFBIG || c_errno == EDQUOT)) {
    system = c_errno;
  }
  if (code == SQLITE_FULL || ((code == SQLITE_IOERR || code == SQLITE_CANTOPEN) &&
                              (system == ENOSPC || system == EFBIG || system == EDQUOT))) {
    why += " (" + core::WriteErrorText(system != 0 ? system : ENOSPC) + ")";
  } else if ((code == SQLITE_IOERR || code == SQLITE_CANTOPEN || code == SQLITE_READONLY) && system != 0) {
    why += std::string(" (") + std::strerror(system) + ")";
  } else if (code == SQLITE_IOERR) {
    why += " (the operating system refused a read or write: is the disk full, or the file too large?)";
  } else if (code == SQLITE_BUSY || code == SQLITE_LOCKED) {
    why += " (another process is writing to the file and kept it locked; stop it or run this again later)";
  }
  return why;
}

/// Runs SQL without results; throws core::Error (runtime) naming the file and the reason.
inline void Execute(sqlite3* db, const std::string& sql, const std::filesystem::path& file) {
  if (sqlite3_exec(db, sql.c_str(), nullptr, nullptr, nullptr) != SQLITE_OK) {
    core::ThrowRuntime(file.string() + ": SQLite: " + Why(db));
  }
}

/// A prepared statement that finalizes itself. Throws core::Error (runtime) naming the file
/// and the SQL when it cannot be prepared.
class Statement {
 public:
  Statement(sqlite3* db, const char* sql, const std::filesystem::path& file) {
    if (sqlite3_prepare_v2(db, sql, -1, &statement_, nullptr) != SQLITE_OK) {
      core::ThrowRuntime(file.string() + ": SQLite cannot prepare '" + sql + "': " + Why(db));
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
