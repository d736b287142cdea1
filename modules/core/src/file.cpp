#include "mosaicloc/core/file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <string>

#include "mosaicloc/core/error.hpp"

namespace mosaicloc::core {
namespace {

// Writes everything to fd; the errno of the failure, or 0.
int WriteAll(int fd, std::string_view content) {
  const char* data = content.data();
  std::size_t left = content.size();
  while (left > 0) {
    const ssize_t written = ::write(fd, data, left);
    if (written < 0) {
      if (errno == EINTR) continue;
      return errno;
    }
    data += written;
    left -= static_cast<std::size_t>(written);
  }
  return 0;
}

}  // namespace

std::string WriteErrorText(int error_number) {
  std::string text = std::strerror(error_number);
  if (error_number == ENOSPC || error_number == EDQUOT || error_number == EFBIG) {
    text += ": the disk is full or the file may not grow; free space and run it again";
  }
  return text;
}

void WriteFileAtomically(const std::filesystem::path& file, std::string_view content) {
  static std::atomic<unsigned> counter{0};
  const std::filesystem::path directory = file.has_parent_path() ? file.parent_path() : ".";
  const std::filesystem::path temporary =
      directory / ("." + file.filename().string() + ".tmp." + std::to_string(::getpid()) + "." +
                   std::to_string(counter++));
  const auto fail = [&](const std::string& what, int error_number) {
    std::error_code ignored;
    std::filesystem::remove(temporary, ignored);
    core::ThrowRuntime(file.string() + ": cannot write (" + what + " " + temporary.string() + ": " +
                       WriteErrorText(error_number) + ")");
  };
  const int fd = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) fail("create", errno);
  if (const int error_number = WriteAll(fd, content); error_number != 0) {
    ::close(fd);
    fail("write", error_number);
  }
  if (::fsync(fd) != 0) {
    const int error_number = errno;
    ::close(fd);
    fail("sync", error_number);
  }
  if (::close(fd) != 0) fail("close", errno);
  std::error_code ec;
  std::filesystem::rename(temporary, file, ec);
  if (ec) fail("rename", ec.value());
}

void WriteFile(const std::filesystem::path& file, std::string_view content) {
  const int fd = ::open(file.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) core::ThrowRuntime(file.string() + ": cannot create (" + WriteErrorText(errno) + ")");
  int error_number = WriteAll(fd, content);
  if (::close(fd) != 0 && error_number == 0) error_number = errno;
  if (error_number != 0) core::ThrowRuntime(file.string() + ": cannot write (" + WriteErrorText(error_number) + ")");
}

}  // namespace mosaicloc::core
