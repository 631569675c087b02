#include "tools/fogctl/report_text.hpp"

#include <cmath>
#include <cstdio>
#include <sstream>

namespace fogmap::cli {

std::string fixedText(double v, int digits) {
  if (!std::isfinite(v)) return "n/a";
  char text[64];
  std::snprintf(text, sizeof text, "%.*f", digits, v);
  return text;
}

std::string jsonNumber(double v) {
  if (!std::isfinite(v)) return "null";
  std::ostringstream out;
  out.precision(10);
  out << v;
  return out.str();
}

}  // namespace fogmap::cli
