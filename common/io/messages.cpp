#include "common/io/messages.hpp"

namespace fogmap {

const char* modeName(Mode mode) {
  switch (mode) {
    case Mode::kMadc: return "madc";
    case Mode::kBaseline: return "baseline";
    case Mode::kExt: return "ext";
  }
  return "madc";
}

}  // namespace fogmap
