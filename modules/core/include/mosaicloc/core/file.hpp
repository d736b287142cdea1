#pragma once

#include <filesystem>
#include <string>
#include <string_view>

namespace mosaicloc::core {

/// Writes `content` to a hidden temporary file beside `file`, flushes it to disk, then renames
/// it over `file`: a reader, a crash or a power cut sees either the old file or the complete
/// new one, never a partial write. Throws core::Error (runtime) naming the file on failure.
void WriteFileAtomically(const std::filesystem::path& file, std::string_view content);

/// Writes `content` to `file` (created or truncated) in place: for the files of a staging
/// directory that is renamed into place whole. Throws core::Error (runtime) naming the file
/// and the operating system's reason.
void WriteFile(const std::filesystem::path& file, std::string_view content);

/// The operating system's reason for a failed write (strerror), and what to do where the disk
/// is full or the file may not grow (ENOSPC, EDQUOT, EFBIG).
std::string WriteErrorText(int error_number);

}  // namespace mosaicloc::core
