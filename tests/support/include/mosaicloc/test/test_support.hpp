#pragma once

#include <filesystem>
#include <optional>
#include <string>

#include <opencv2/core/mat.hpp>

namespace mosaicloc::test {

/// A fresh directory under the system temporary directory, removed on destruction.
class ScratchDir {
 public:
  ScratchDir();
  ~ScratchDir();
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

/// The shared data folder (real floor textures), from $MOSAICLOC_SHARED_DATA, or nothing
/// when it is absent. Tests that need it call GTEST_SKIP() with SharedDataMissingMessage().
std::optional<std::filesystem::path> SharedDataDir();
/// A texture file in the shared data folder, or nothing if missing.
std::optional<std::filesystem::path> SharedTexture(const std::string& name);
std::string SharedDataMissingMessage();

/// The whole content of a file as a string (binary).
std::string ReadFile(const std::filesystem::path& file);
/// Writes (replaces) a file.
void WriteFile(const std::filesystem::path& file, const std::string& content);

/// A TCP port on loopback that nobody listens on now (the system's pick), for a test's server.
int FreeLoopbackPort();

/// Zero-normalized cross-correlation of two images of the same size over the pixels where
/// mask (CV_8UC1) is non-zero; 1 for images equal up to gain and offset.
double Zncc(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask);

}  // namespace mosaicloc::test
