#include "tools/fogctl/args.hpp"

#include <cmath>
#include <cstdlib>
#include <iostream>

namespace fogmap::cli {

Expected<Args> Args::parse(int argc, char** argv, int first, const std::set<std::string>& valued,
                           const std::set<std::string>& switches) {
  Args args;
  for (int i = first; i < argc; ++i) {
    const std::string token = argv[i];
    if (token.rfind("--", 0) != 0) {
      args.positional_.push_back(token);
      continue;
    }
    const std::string name = token.substr(2);
    if (switches.count(name) > 0) {
      args.values_[name] = "1";
    } else if (valued.count(name) > 0) {
      if (i + 1 >= argc) return invalidArgument("flag --" + name + " needs a value");
      args.values_[name] = argv[++i];
    } else {
      return invalidArgument("unknown flag --" + name);
    }
  }
  return args;
}

std::string Args::get(const std::string& name, const std::string& fallback) const {
  const auto it = values_.find(name);
  return it == values_.end() ? fallback : it->second;
}

Expected<double> Args::getDouble(const std::string& name, double fallback) const {
  const auto it = values_.find(name);
  if (it == values_.end()) return fallback;
  char* end = nullptr;
  const double v = std::strtod(it->second.c_str(), &end);
  if (end == it->second.c_str() || *end != '\0' || !std::isfinite(v)) {
    return invalidArgument("--" + name + " expects a number, got '" + it->second + "'");
  }
  return v;
}

Expected<long> Args::getInt(const std::string& name, long fallback) const {
  const auto it = values_.find(name);
  if (it == values_.end()) return fallback;
  char* end = nullptr;
  const long v = std::strtol(it->second.c_str(), &end, 10);
  if (end == it->second.c_str() || *end != '\0') {
    return invalidArgument("--" + name + " expects an integer, got '" + it->second + "'");
  }
  return v;
}

int fail(const Error& error, const std::string& who) {
  std::cerr << who << ": " << error.message << "\n";
  return error.code == ErrorCode::kInvalidArgument ? 2 : 1;
}

}  // namespace fogmap::cli
