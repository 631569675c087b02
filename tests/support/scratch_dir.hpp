#pragma once
// Files for tests: a fresh directory of their own, one kept for a cluster's files, where to keep
// pictures for a person to look at, and a file's bytes read back.
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <system_error>

namespace fogmap::test_support {

// A fresh directory under the system temp dir, named by `name` and the process id (so test binaries
// running side by side never share one); removed with everything in it at the end.
class ScratchDir {
 public:
  explicit ScratchDir(const std::string& name)
      : path_(std::filesystem::temp_directory_path() / ("fogmap-test-" + std::to_string(::getpid()) + "-" + name)) {
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~ScratchDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

// A fresh directory for the files of a cluster run (its nodes' logs), under the system temp dir and
// named by `name` and the process id; kept after the test, for a person to read after a failure.
inline std::filesystem::path keptDir(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / ("fogmap-it-" + std::to_string(::getpid()) + "-" + name);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

// Where a test writes what a person may want to look at: the directory the environment variable
// `variable` names (created if need be) when it is set, else `scratch`.
inline std::filesystem::path outputDir(const char* variable, const ScratchDir& scratch) {
  const char* named = std::getenv(variable);
  if (named == nullptr) return scratch.path();
  std::filesystem::create_directories(named);
  return named;
}

// The bytes of `file`; empty when it cannot be read.
inline std::string readFile(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace fogmap::test_support
