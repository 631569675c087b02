#pragma once
// Minimal "--flag value" parsing for fogctl subcommands; unknown flags are errors.
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "common/status.hpp"

namespace fogmap::cli {

class Args {
 public:
  // Parses argv[first..argc) as "--name value" pairs and bare "--switch" flags (listed in `switches`).
  static Expected<Args> parse(int argc, char** argv, int first, const std::set<std::string>& valued,
                              const std::set<std::string>& switches);

  bool has(const std::string& name) const { return values_.count(name) > 0; }
  std::string get(const std::string& name, const std::string& fallback = "") const;
  Expected<double> getDouble(const std::string& name, double fallback) const;
  Expected<long> getInt(const std::string& name, long fallback) const;
  const std::vector<std::string>& positional() const { return positional_; }

 private:
  std::map<std::string, std::string> values_;
  std::vector<std::string> positional_;
};

// Prints "WHO: message" on stderr and returns the exit code: 2 for invalid arguments, else 1.
int fail(const Error& error, const std::string& who = "fogctl");

}  // namespace fogmap::cli
