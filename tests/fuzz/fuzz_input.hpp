#pragma once

// What every fuzz target shares: the input as the file a reader would be given, and the rule
// that bad input gets a core::Error and nothing else (a crash, another exception, a sanitizer
// report or a hang is a finding).

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
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

/// As a hostile client would: connects to the loopback `port`, sends the bytes, says it sends
/// no more and reads what comes back until the server closes, has been quiet for `quiet_ms`
/// or has sent for `max_ms` (a stream). Returns the bytes received.
inline std::size_t Exchange(int port, const std::uint8_t* data, std::size_t size, int quiet_ms = 200,
                            int max_ms = 500) {
  const int s = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  address.sin_port = htons(static_cast<std::uint16_t>(port));
  if (connect(s, reinterpret_cast<sockaddr*>(&address), sizeof(address)) != 0) {
    close(s);
    return 0;
  }
  for (std::size_t sent = 0; sent < size;) {
    const ssize_t n = send(s, data + sent, size - sent, MSG_NOSIGNAL);
    if (n <= 0) break;
    sent += static_cast<std::size_t>(n);
  }
  shutdown(s, SHUT_WR);
  std::size_t received = 0;
  char buffer[4096];
  pollfd readable{s, POLLIN, 0};
  const auto until = std::chrono::steady_clock::now() + std::chrono::milliseconds(max_ms);
  while (std::chrono::steady_clock::now() < until && poll(&readable, 1, quiet_ms) > 0) {
    const ssize_t n = recv(s, buffer, sizeof(buffer), 0);
    if (n <= 0) break;
    received += static_cast<std::size_t>(n);
  }
  close(s);
  return received;
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
