#include "pictures/drawing.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace fogmap::pictures::drawing {
namespace {

constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;

}  // namespace

cv::Scalar bgr(const Rgb& c) { return {static_cast<double>(c.b), static_cast<double>(c.g), static_cast<double>(c.r)}; }

cv::Point fixedPoint(const Eigen::Vector2d& px) {
  const auto fixed = [](double v) { return static_cast<int>(std::lround(std::clamp(v - 0.5, -kFar, kFar) * kFixed)); };
  return {fixed(px.x()), fixed(px.y())};
}

int fixedLength(double px) { return static_cast<int>(std::lround(px * kFixed)); }

cv::Size Pen::size(const std::string& text) const {
  int baseline = 0;
  return cv::getTextSize(text, kFont, scale, thickness, &baseline);
}

int Pen::descent() const {
  int baseline = 0;
  cv::getTextSize("gy", kFont, scale, thickness, &baseline);
  return baseline;
}

void Pen::write(cv::Mat& image, const std::string& text, cv::Point at, const cv::Scalar& colour) const {
  cv::putText(image, text, at, kFont, scale, colour, thickness, cv::LINE_AA);
}

void Pen::writeOnMap(cv::Mat& image, const std::string& text, cv::Point at, const cv::Scalar& colour) const {
  cv::putText(image, text, at, kFont, scale, cv::Scalar(255, 255, 255), thickness + 3, cv::LINE_AA);
  write(image, text, at, colour);
}

std::vector<std::string> Pen::wrap(const std::string& text, int width) const {
  std::vector<std::string> lines;
  std::string line;
  std::size_t start = 0;
  while (start <= text.size()) {
    const std::size_t end = std::min(text.find(' ', start), text.size());
    const std::string word = text.substr(start, end - start);
    const std::string longer = line.empty() ? word : line + " " + word;
    if (!line.empty() && size(longer).width > width) {
      lines.push_back(line);
      line = word;
    } else {
      line = longer;
    }
    start = end + 1;
  }
  if (!line.empty()) lines.push_back(line);
  return lines;
}

Pen Pen::shrunkToFit(const std::string& text, int width, double min_scale) const {
  Pen pen = *this;
  while (pen.size(text).width > width && pen.scale > min_scale) pen.scale *= 0.92;
  return pen;
}

double niceStep(double span, int count) {
  const double raw = span / std::max(1, count);
  double decade = std::pow(10.0, std::floor(std::log10(raw)));
  for (;; decade *= 10.0) {
    for (const double m : {1.0, 2.0, 5.0}) {
      if (m * decade >= raw * (1.0 - 1e-9)) return m * decade;
    }
  }
}

std::vector<double> multiplesIn(double lo, double hi, double step) {
  std::vector<double> out;
  const double first = std::ceil(lo / step - 1e-9);
  for (int i = 0; i < 1000; ++i) {
    double v = (first + i) * step;
    if (v > hi + step * 1e-9) break;
    if (std::abs(v) < step * 1e-9) v = 0.0;  // no "-0"
    out.push_back(v);
  }
  return out;
}

Status writePng(const std::filesystem::path& png, const cv::Mat& image, const std::string& what) {
  std::vector<unsigned char> bytes;
  try {
    if (!cv::imencode(".png", image, bytes)) return Error{ErrorCode::kInternal, what + ": PNG encoding failed for " + png.string()};
  } catch (const cv::Exception& e) {
    return Error{ErrorCode::kInternal, what + ": PNG encoding failed for " + png.string() + ": " + e.what()};
  }
  errno = 0;
  std::ofstream out(png, std::ios::binary | std::ios::trunc);
  if (!out) return ioError("cannot write " + png.string() + (errno != 0 ? std::string(": ") + std::strerror(errno) : std::string()));
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  out.close();
  if (!out) return ioError("cannot write " + png.string() + (errno != 0 ? std::string(": ") + std::strerror(errno) : std::string()));
  return {};
}

}  // namespace fogmap::pictures::drawing
