#include "mosaicloc/test/test_support.hpp"

#include <opencv2/core.hpp>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace mosaicloc::test {

int FreeLoopbackPort() {
  const int s = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  bind(s, reinterpret_cast<sockaddr*>(&address), sizeof(address));
  socklen_t length = sizeof(address);
  getsockname(s, reinterpret_cast<sockaddr*>(&address), &length);
  close(s);
  return ntohs(address.sin_port);
}

ScratchDir::ScratchDir() {
  static std::atomic<int> counter{0};
  path_ = std::filesystem::temp_directory_path() /
          ("mosaicloc-test-" + std::to_string(::getpid()) + "-" + std::to_string(counter++));
  std::filesystem::remove_all(path_);
  std::filesystem::create_directories(path_);
}

ScratchDir::~ScratchDir() {
  std::error_code ec;
  std::filesystem::remove_all(path_, ec);
}

std::optional<std::filesystem::path> SharedDataDir() {
  const char* env = std::getenv("MOSAICLOC_SHARED_DATA");
  if (env == nullptr || *env == '\0') return std::nullopt;
  const std::filesystem::path dir(env);
  std::error_code ec;
  if (!std::filesystem::is_directory(dir / "textures", ec)) return std::nullopt;
  return dir;
}

std::optional<std::filesystem::path> SharedTexture(const std::string& name) {
  const auto dir = SharedDataDir();
  if (!dir) return std::nullopt;
  const auto file = *dir / "textures" / name;
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) return std::nullopt;
  return file;
}

std::string SharedDataMissingMessage() {
  const char* env = std::getenv("MOSAICLOC_SHARED_DATA");
  return std::string("shared data folder with real textures not found (MOSAICLOC_SHARED_DATA=") +
         (env ? env : "unset") + "): skipped; it sits beside the project as ../shared/data";
}

std::string ReadFile(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + file.string());
  std::ostringstream content;
  content << in.rdbuf();
  return content.str();
}

void WriteFile(const std::filesystem::path& file, const std::string& content) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  if (!out) throw std::runtime_error("cannot write " + file.string());
  out << content;
}

double Zncc(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask) {
  cv::Mat fa;
  cv::Mat fb;
  a.convertTo(fa, CV_64F);
  b.convertTo(fb, CV_64F);
  fa -= cv::mean(fa, mask)[0];
  fb -= cv::mean(fb, mask)[0];
  fa.setTo(0, mask == 0);
  fb.setTo(0, mask == 0);
  return fa.dot(fb) / std::sqrt(fa.dot(fa) * fb.dot(fb));
}

}  // namespace mosaicloc::test
