#include "common/base/text.hpp"

#include <sstream>

namespace fogmap {

std::string readableNumber(double value) {
  std::ostringstream out;
  out << value;
  return out.str();
}

}  // namespace fogmap
