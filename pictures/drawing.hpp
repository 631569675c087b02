#pragma once
// What every fogmap picture shares (bird's-eye views, line charts): sub-pixel coordinates in
// OpenCV's fixed point, one font through a Pen, colours in OpenCV's order, nice grid steps, and
// writing the PNG. Internal to fogmap::pictures: OpenCV stays out of birdseye.hpp and plot.hpp.
#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "common/base/status.hpp"
#include "pictures/birdseye.hpp"  // Rgb: one colour type for fogctl's pictures

namespace fogmap::pictures::drawing {

// Lines are drawn with kShift fractional bits: sub-pixel positions, anti-aliased.
inline constexpr int kShift = 4;
inline constexpr double kFixed = 1 << kShift;
inline constexpr double kFar = 1 << 20;  // pixel coordinates are clamped here, far outside any picture

// The ink every picture shares (BGR): frames, text, and text that steps back (captions, units).
inline const cv::Scalar kFrameColour(90, 90, 90);
inline const cv::Scalar kTextColour(30, 30, 30);
inline const cv::Scalar kMutedTextColour(90, 90, 90);

// `c` as an OpenCV colour (blue, green, red).
cv::Scalar bgr(const Rgb& c);

// A continuous pixel position (pixel (i, j) covers [i, i + 1) x [j, j + 1)) as OpenCV's fixed-point
// drawing coordinate (pixel centres at integers), clamped to kFar.
cv::Point fixedPoint(const Eigen::Vector2d& px);

// A length in pixels in fixed point (a radius for cv::circle with kShift).
int fixedLength(double px);

// Text in one font, anti-aliased; `scale` is the font scale, the baseline at `at`.
struct Pen {
  double scale = 0.5;
  int thickness = 1;

  // The size of `text` above its baseline.
  cv::Size size(const std::string& text) const;
  // How far descenders ("g", "y") reach below the baseline.
  int descent() const;
  void write(cv::Mat& image, const std::string& text, cv::Point at, const cv::Scalar& colour) const;
  // Text over data: a white halo first so it reads on any background.
  void writeOnMap(cv::Mat& image, const std::string& text, cv::Point at, const cv::Scalar& colour) const;
  // Splits `text` at spaces into lines no wider than `width` pixels (a longer word stays whole).
  std::vector<std::string> wrap(const std::string& text, int width) const;
  // This pen, its scale cut by 8 % at a time until `text` is no wider than `width` or the scale
  // is no more than `min_scale`.
  Pen shrunkToFit(const std::string& text, int width, double min_scale) const;
};

// The smallest step of 1, 2, 5 x 10^k with at most `count` steps across `span` (> 0).
double niceStep(double span, int count);

// The multiples of `step` (> 0) in [lo, hi], ascending, zero as +0 (at most 1000).
std::vector<double> multiplesIn(double lo, double hi, double step);

// Encodes `image` as PNG into the file `png`. `what` names the caller in errors ("plot").
// Errors: encoding fails (kInternal); the file cannot be written (kIo, naming it).
Status writePng(const std::filesystem::path& png, const cv::Mat& image, const std::string& what);

}  // namespace fogmap::pictures::drawing
