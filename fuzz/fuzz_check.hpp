#pragma once
// What the fuzz targets share: properties every answer must have. A failed property aborts, so
// libFuzzer keeps the input as a finding like any crash or sanitizer report.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include "common/io/cloud_io.hpp"
#include "common/base/status.hpp"

namespace fogmap::fuzz {

inline void check(bool holds, const char* property) {
  if (holds) return;
  std::fprintf(stderr, "fogmap fuzz: property violated: %s\n", property);
  std::abort();
}

// A round trip that must succeed: on failure the property and the error say what went wrong.
template <class T>
void checkOk(const Expected<T>& result, const char* property) {
  if (result.ok()) return;
  std::fprintf(stderr, "fogmap fuzz: property violated: %s: %s\n", property, result.error().message.c_str());
  std::abort();
}

// Bad input is an error a person can act on: an invalid argument whose message starts with
// `prefix` (the file or document it is about) and says more than that.
inline void checkRejection(const Error& error, std::string_view prefix) {
  check(error.code == ErrorCode::kInvalidArgument, "bad input is reported as an invalid argument");
  check(error.message.starts_with(prefix) && error.message.size() > prefix.size() + 8,
        "the error names the input and the problem");
}

// A cloud reader's answer: an error about `name`, or points that are finite unless kept, counted.
inline void checkLoaded(const Expected<LoadedCloud>& loaded, const std::string& name, const ReadLimits& limits) {
  if (!loaded) {
    checkRejection(loaded.error(), name + ": ");
    return;
  }
  std::size_t non_finite = 0;
  for (const Point& p : loaded->points) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) ++non_finite;
  }
  check(non_finite == loaded->kept_non_finite, "kept_non_finite counts the non-finite points kept");
  check(limits.keep_non_finite ? loaded->dropped_non_finite == 0 : loaded->kept_non_finite == 0,
        "non-finite points are either all kept or all dropped");
}

}  // namespace fogmap::fuzz
