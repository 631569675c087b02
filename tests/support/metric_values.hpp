#pragma once
// Reading a service's exported metrics back in tests, from the registry it serves.
#include <string>

#include "services/common/metrics.hpp"

namespace fogmap::test_support {

// The sum of the counter series of `family` that carry the label `label`=`value`.
inline double counterValue(Metrics& metrics, const std::string& family, const std::string& label, const std::string& value) {
  double sum = 0.0;
  for (const auto& f : metrics.registry().Collect()) {
    if (f.name != family) continue;
    for (const auto& m : f.metric) {
      for (const auto& l : m.label) {
        if (l.name == label && l.value == value) sum += m.counter.value;
      }
    }
  }
  return sum;
}

}  // namespace fogmap::test_support
