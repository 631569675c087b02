#pragma once
// Detector networks whose answer a test knows: tests/data/make_tiny_detector.py writes an ONNX
// graph that always outputs a given table (Debian's python3-onnx builds it at test time).
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace fogmap::test_support {

// A Python that can import onnx. Debian's python3-onnx installs for the system interpreter, which
// a python3 earlier on PATH (a virtualenv, pyenv) may not see.
inline std::optional<std::string> pythonWithOnnx() {
  for (const std::string candidate : {"python3", "/usr/bin/python3"}) {
    if (std::system((candidate + " -c 'import onnx' >/dev/null 2>&1").c_str()) == 0) return candidate;
  }
  return std::nullopt;
}

// Builds a network whose output is `rows` (see make_tiny_detector.py) with an input of
// height x width, and returns its path; empty on failure.
inline std::filesystem::path makeTinyDetector(const std::string& python, const std::filesystem::path& dir, const std::string& layout, int height, int width,
                          const std::vector<std::string>& rows) {
  const std::filesystem::path model = dir / (layout + ".onnx");
  std::string command = python + " '" + (std::filesystem::path(FOGMAP_SOURCE_DIR) / "tests/data/make_tiny_detector.py").string() + "' '" +
                        model.string() + "' " + layout + " " + std::to_string(height) + " " + std::to_string(width);
  for (const std::string& row : rows) command += " " + row;
  if (std::system(command.c_str()) != 0) return {};
  return model;
}

#define SKIP_WITHOUT_ONNX(python)                                                                                  \
  const std::optional<std::string> python = pythonWithOnnx();                                                      \
  if (!python) GTEST_SKIP() << "no python3 with the onnx module (Debian: python3-onnx); the dnn path is untested"

}  // namespace fogmap::test_support
