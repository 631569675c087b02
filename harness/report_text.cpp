#include "harness/report_text.hpp"

#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <fstream>

namespace fogmap::harness {

std::string fixedText(double v, int digits) {
  if (!std::isfinite(v)) return "n/a";
  char text[64];
  std::snprintf(text, sizeof text, "%.*f", digits, v);
  return text;
}

std::string formatText(const char* format, ...) {
  va_list args;
  va_start(args, format);
  va_list again;
  va_copy(again, args);
  const int n = std::vsnprintf(nullptr, 0, format, args);
  va_end(args);
  std::string out(n > 0 ? static_cast<std::size_t>(n) + 1 : 1, '\0');
  if (n > 0) std::vsnprintf(out.data(), out.size(), format, again);
  va_end(again);
  out.resize(n > 0 ? static_cast<std::size_t>(n) : 0);
  return out;
}

Json jsonNumber(double v) {
  if (!std::isfinite(v)) return nullptr;
  char text[64];
  std::snprintf(text, sizeof text, "%.10g", v);
  return std::strtod(text, nullptr);
}

std::string jsonText(const Json& report) {
  return report.dump(2, ' ', false, Json::error_handler_t::replace) + "\n";
}

Status writeTextFile(const std::filesystem::path& file, const std::string& text) {
  std::ofstream out(file);
  out << text;
  if (!out) return ioError("cannot write " + file.string());
  return {};
}

}  // namespace fogmap::harness
