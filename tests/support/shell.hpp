#pragma once
// Runs a shell command for the tests that drive fogctl and other programs as a user would: its exit
// code and what it printed (stdout and stderr together).
#include <sys/wait.h>

#include <cstdio>
#include <string>
#include <utility>

namespace fogmap::test_support {

inline std::pair<int, std::string> runCommand(const std::string& command) {
  std::string output;
  FILE* pipe = ::popen((command + " 2>&1").c_str(), "r");
  if (pipe == nullptr) return {-1, ""};
  char buffer[4096];
  while (std::fgets(buffer, sizeof buffer, pipe) != nullptr) output += buffer;
  const int status = ::pclose(pipe);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, output};
}

}  // namespace fogmap::test_support
