#pragma once

// What every fuzz target shares: the input as the file a reader would be given, and the rule
// that bad input gets a core::Error and nothing else (a crash, another exception, a sanitizer
// report or a hang is a finding).

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::fuzz {

/// A directory of this process's own, for the files the readers open.
inline const std::filesystem::path& ScratchDir() {
  static const std::filesystem::path dir = [] {
    const char* base = std::getenv("TMPDIR");
    std::filesystem::path path = std::filesystem::path(base != nullptr ? base : "/tmp") /
                                 ("mosaicloc-fuzz-" + std::to_string(::getpid()));
    std::filesystem::create_directories(path);
    return path;
  }();
  return dir;
}

/// Writes `size` bytes to `file` (replacing it).
inline void WriteBytes(const std::filesystem::path& file, const std::uint8_t* data, std::size_t size) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
}

/// Runs `read`; a core::Error (the answer to bad input) is swallowed, anything else escapes.
template <typename Read>
void ExpectOnlyCoreErrors(Read&& read) {
  try {
    read();
  } catch (const core::Error&) {
  }
}

}  // namespace mosaicloc::fuzz
