#pragma once

#include <filesystem>
#include <string_view>

namespace mosaicloc::core {

/// Writes `content` to a hidden temporary file beside `file`, flushes it to disk, then renames
/// it over `file`: a reader, a crash or a power cut sees either the old file or the complete
/// new one, never a partial write. Throws core::Error (runtime) naming the file on failure.
void WriteFileAtomically(const std::filesystem::path& file, std::string_view content);

}  // namespace mosaicloc::core
