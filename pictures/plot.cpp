#include "pictures/plot.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "pictures/drawing.hpp"

namespace fogmap::pictures {
namespace {

using drawing::bgr;
using drawing::fixedLength;
using drawing::fixedPoint;
using drawing::kFar;
using drawing::kFrameColour;
using drawing::kMutedTextColour;
using drawing::kShift;
using drawing::kTextColour;
using drawing::multiplesIn;
using drawing::niceStep;
using drawing::Pen;

constexpr int kMarkerCount = 6;
const cv::Scalar kPlotGridColour(228, 228, 228);
const cv::Scalar kMinorGridColour(245, 245, 245);
const cv::Scalar kLegendFrameColour(200, 200, 200);
const cv::Scalar kLegendFillColour(251, 251, 251);
const cv::Scalar kWhite(255, 255, 255);

// Sizes grow with the picture; 900 x 560 is the unit.
double unitOf(int width_px, int height_px) { return std::max(0.5, std::min(width_px / 900.0, height_px / 560.0)); }

struct Pens {
  Pen tick, axis, legend, title;
  explicit Pens(double unit) : tick{0.5 * unit, 1}, axis{0.55 * unit, 1}, legend{0.5 * unit, 1}, title{0.7 * unit, 2} {}
};

std::string sizeText(int width_px, int height_px) { return std::to_string(width_px) + " x " + std::to_string(height_px); }

std::string seriesName(const PlotSeries& s, std::size_t index) {
  return "series " + std::to_string(index) + (s.name.empty() ? std::string() : " ('" + s.name + "')");
}

Status validate(const PlotSpec& spec, int width_px, int height_px) {
  if (width_px < 320 || width_px > 8000 || height_px < 240 || height_px > 8000) {
    return invalidArgument("plot: the size must be in [320, 8000] x [240, 8000] pixels, not " + sizeText(width_px, height_px));
  }
  if (spec.series.empty()) return invalidArgument("plot: no series to draw");
  const auto bad_bound = [&](const std::optional<double>& v) {
    return v.has_value() && (!std::isfinite(*v) || (spec.log_y && *v <= 0.0));
  };
  if (bad_bound(spec.y_min) || bad_bound(spec.y_max)) {
    return invalidArgument(spec.log_y ? "plot: y_min and y_max must be finite and positive on a log axis" : "plot: y_min and y_max must be finite");
  }
  if (spec.y_min && spec.y_max && !(*spec.y_min < *spec.y_max)) return invalidArgument("plot: y_min must be less than y_max");
  for (const double t : spec.x_ticks) {
    if (!std::isfinite(t)) return invalidArgument("plot: the explicit x ticks must be finite");
  }
  if (!(spec.dodge_px >= 0.0 && spec.dodge_px <= 40.0)) return invalidArgument("plot: dodge_px must be in [0, 40] pixels");
  bool any_y = false;
  for (std::size_t i = 0; i < spec.series.size(); ++i) {
    const PlotSeries& s = spec.series[i];
    const std::size_t n = s.x.size();
    if (s.y.size() != n) {
      return invalidArgument("plot: " + seriesName(s, i) + " has " + std::to_string(n) + " x values but " + std::to_string(s.y.size()) + " y values");
    }
    for (const auto* range : {&s.y_low, &s.y_high}) {
      if (!range->empty() && range->size() != n) {
        return invalidArgument("plot: " + seriesName(s, i) + " has " + std::to_string(n) + " points but " + std::to_string(range->size()) + " " +
                               (range == &s.y_low ? "y_low" : "y_high") + " values (give none or one per point)");
      }
    }
    for (std::size_t k = 0; k < n; ++k) {
      if (!std::isfinite(s.x[k])) return invalidArgument("plot: " + seriesName(s, i) + " has a non-finite x at point " + std::to_string(k));
      for (const auto* values : {&s.y, &s.y_low, &s.y_high}) {
        if (values->empty()) continue;
        const double v = (*values)[k];
        if (std::isinf(v)) return invalidArgument("plot: " + seriesName(s, i) + " has an infinite y at point " + std::to_string(k));
        if (spec.log_y && !std::isnan(v) && v <= 0.0) {
          return invalidArgument("plot: " + seriesName(s, i) + " has y = " + std::to_string(v) + " at point " + std::to_string(k) +
                                 ", which a log axis cannot show (values must be positive)");
        }
      }
      any_y = any_y || std::isfinite(s.y[k]);
    }
  }
  if (!any_y) return invalidArgument("plot: no series has a finite y value: nothing to draw");
  return {};
}

// Nice ticks: the multiples inside [lo, hi] of the nice step for at most `count` steps (at least
// two ticks, if need be with a finer step).
std::vector<double> niceTicks(double lo, double hi, int count, double* step_out) {
  double step = niceStep(hi - lo, count);
  std::vector<double> ticks = multiplesIn(lo, hi, step);
  for (int i = 0; i < 4 && ticks.size() < 2; ++i) {
    step = niceStep(hi - lo, count * 2 + 2);
    count = count * 2 + 2;
    ticks = multiplesIn(lo, hi, step);
  }
  if (step_out != nullptr) *step_out = step;
  return ticks;
}

// "1", "10", "100", "1k", "20k", "1M", ... and "0.1", "0.01", ...: short labels for values on a log axis.
std::string siLabel(double v) {
  static const char* const kSuffix[] = {"", "k", "M", "G", "T", "P"};
  char text[48];
  if (std::abs(v) >= 1000.0) {
    int group = std::min(5, static_cast<int>(std::floor(std::log10(std::abs(v)) / 3.0 + 1e-9)));
    std::snprintf(text, sizeof(text), "%.3g%s", v / std::pow(1000.0, group), kSuffix[group]);
  } else {
    std::snprintf(text, sizeof(text), "%.3g", v);
  }
  return text;
}

// Labels for linear ticks `step` apart: as many decimals as the step needs (up to 4, then 2e-05
// style), thousands as k, M, G.
std::vector<std::string> linearLabels(const std::vector<double>& ticks, double step) {
  double largest = 0.0;
  for (const double t : ticks) largest = std::max(largest, std::abs(t));
  static const char* const kSuffix[] = {"", "k", "M", "G", "T", "P"};
  int group = 0;
  if (largest >= 1e4) group = std::min(5, static_cast<int>(std::floor(std::log10(largest) / 3.0 + 1e-9)));
  const double scale = std::pow(1000.0, group);
  const int decimals = std::clamp(static_cast<int>(-std::floor(std::log10(step / scale) + 1e-9)), 0, 12);
  std::vector<std::string> out;
  for (const double t : ticks) {
    char text[64];
    if (decimals > 4) {
      std::snprintf(text, sizeof(text), "%.3g", t);  // tiny steps: 2e-05 reads better than 0.00002
    } else {
      std::snprintf(text, sizeof(text), "%.*f%s", decimals, t / scale, t == 0.0 ? "" : kSuffix[group]);
    }
    out.push_back(text);
  }
  return out;
}

struct LogTicks {
  std::vector<double> major, minor;
};

// Decades inside [10^llo, 10^lhi] (every n-th if there are many); with fewer than two decades,
// 1, 2, 5 x 10^k (or 1..9 x 10^k) instead.
LogTicks logTicks(double llo, double lhi, int count) {
  LogTicks t;
  const int first = static_cast<int>(std::ceil(llo - 1e-9));
  const int last = static_cast<int>(std::floor(lhi + 1e-9));
  if (last - first + 1 >= 2) {
    const int every = std::max(1, (last - first + count) / std::max(1, count));
    for (int k = first; k <= last; ++k) {
      if ((k - first) % every == 0) t.major.push_back(std::pow(10.0, k));
    }
    if (every == 1) {
      for (int k = first - 1; k <= last; ++k) {
        for (int m = 2; m <= 9; ++m) {
          const double v = m * std::pow(10.0, k);
          const double lv = std::log10(v);
          if (lv >= llo - 1e-9 && lv <= lhi + 1e-9) t.minor.push_back(v);
        }
      }
    }
    return t;
  }
  for (const std::vector<int>& mantissas : {std::vector<int>{1, 2, 5}, std::vector<int>{1, 2, 3, 4, 5, 6, 7, 8, 9}}) {
    t.major.clear();
    for (int k = first - 1; k <= last; ++k) {
      for (const int m : mantissas) {
        const double v = m * std::pow(10.0, k);
        const double lv = std::log10(v);
        if (lv >= llo - 1e-9 && lv <= lhi + 1e-9) t.major.push_back(v);
      }
    }
    if (t.major.size() >= 2) break;
  }
  return t;
}

// The y range shown: from the data (whiskers too), a margin around it, then the explicit ends.
// With log_y, in log10 units.
std::pair<double, double> yRange(const PlotSpec& spec) {
  const auto to_axis = [&](double v) { return spec.log_y ? std::log10(v) : v; };
  double lo = std::numeric_limits<double>::infinity();
  double hi = -lo;
  for (const auto& s : spec.series) {
    for (const auto* values : {&s.y, &s.y_low, &s.y_high}) {
      for (const double v : *values) {
        if (!std::isfinite(v)) continue;
        lo = std::min(lo, to_axis(v));
        hi = std::max(hi, to_axis(v));
      }
    }
  }
  double pad = 0.05 * (hi - lo);
  if (!(hi - lo > 1e-12 * std::max(1.0, std::abs(hi)))) pad = spec.log_y ? 0.3 : (std::abs(hi) > 0.0 ? 0.1 * std::abs(hi) : 1.0);
  lo -= pad;
  hi += pad;
  const double span = hi - lo;
  if (spec.y_min) lo = to_axis(*spec.y_min);
  if (spec.y_max) hi = to_axis(*spec.y_max);
  if (!(lo < hi)) {  // one end given, on the far side of the data
    if (spec.y_min) hi = lo + span;
    else lo = hi - span;
  }
  return {lo, hi};
}

std::pair<double, double> xRange(const PlotSpec& spec) {
  double lo = std::numeric_limits<double>::infinity();
  double hi = -lo;
  for (const auto& s : spec.series) {
    for (const double v : s.x) {
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
  }
  for (const double v : spec.x_ticks) {
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  if (!std::isfinite(lo)) return {0.0, 1.0};  // only series without points: an empty unit axis
  double pad = 0.04 * (hi - lo);
  if (!(hi - lo > 1e-12 * std::max(1.0, std::abs(hi)))) pad = std::abs(hi) > 0.0 ? 0.1 * std::abs(hi) : 1.0;
  return {lo - pad, hi + pad};
}

// The legend's entries: each series' name wrapped to the panel, then the note on whiskers.
struct LegendText {
  std::vector<std::vector<std::string>> entries;  // one per series
  std::vector<std::string> note;
};

struct LegendMetrics {
  int pad = 0;
  int swatch_w = 0;
  int gap = 0;
  int line_h = 0;
  int entry_gap = 0;
};

LegendMetrics legendMetrics(const Pen& pen, double unit) {
  const auto px = [&](double v) { return static_cast<int>(std::lround(v * unit)); };
  return {px(12), px(46), px(10), static_cast<int>(std::lround(pen.size("Ag").height * 1.75)), px(8)};
}

bool hasWhiskers(const PlotSpec& spec) {
  return std::any_of(spec.series.begin(), spec.series.end(), [](const PlotSeries& s) { return !s.y_low.empty() && !s.y_high.empty(); });
}

// The names are wrapped to `name_width`; the note, written across the panel, to `note_width`.
LegendText legendText(const PlotSpec& spec, const Pen& pen, int name_width, int note_width) {
  LegendText t;
  for (const auto& s : spec.series) t.entries.push_back(pen.wrap(s.name.empty() ? std::string("(unnamed)") : s.name, name_width));
  if (!spec.whisker_note.empty() && hasWhiskers(spec)) t.note = pen.wrap(spec.whisker_note, note_width);
  return t;
}

int legendHeight(const LegendText& t, const LegendMetrics& m) {
  int h = 2 * m.pad;
  for (const auto& e : t.entries) h += static_cast<int>(e.size()) * m.line_h + m.entry_gap;
  if (!t.note.empty()) h += m.entry_gap + static_cast<int>(t.note.size()) * m.line_h;
  return h - m.entry_gap;
}

// Thins labels of ticks at `centres` so that no two written labels come closer than `gap` pixels.
void thinLabels(std::vector<std::string>& labels, const std::vector<double>& centres, const Pen& pen, int gap) {
  double right = -kFar;
  for (std::size_t i = 0; i < labels.size(); ++i) {
    const double half = pen.size(labels[i]).width / 2.0;
    if (centres[i] - half < right + gap) {
      labels[i].clear();
      continue;
    }
    right = centres[i] + half;
  }
}

bool labelsFit(const std::vector<std::string>& labels, const std::vector<double>& centres, const Pen& pen, int gap) {
  for (std::size_t i = 1; i < labels.size(); ++i) {
    const double room = centres[i] - centres[i - 1];
    if (room < (pen.size(labels[i - 1]).width + pen.size(labels[i]).width) / 2.0 + gap) return false;
  }
  return true;
}

// Draws the polyline through `points`, solid or dashed; a dashed line's pattern runs on across corners.
void drawLine(cv::Mat& image, const std::vector<Eigen::Vector2d>& points, const cv::Scalar& colour, int thickness, bool dashed, double unit) {
  if (points.size() < 2) return;
  if (!dashed) {
    std::vector<cv::Point> fixed;
    fixed.reserve(points.size());
    for (const auto& p : points) fixed.push_back(fixedPoint(p));
    cv::polylines(image, fixed, false, colour, thickness, cv::LINE_AA, kShift);
    return;
  }
  const double on_px = 11.0 * unit;
  const double off_px = 8.0 * unit;
  bool on = true;
  double phase = 0.0;  // how far into the current dash or gap
  std::vector<cv::Point> dash = {fixedPoint(points[0])};
  for (std::size_t i = 1; i < points.size(); ++i) {
    const Eigen::Vector2d a = points[i - 1];
    const Eigen::Vector2d b = points[i];
    const double length = (b - a).norm();
    double t = 0.0;
    for (int guard = 0; guard < 100000; ++guard) {
      const double remaining = (on ? on_px : off_px) - phase;
      if (t + remaining >= length) {
        phase += length - t;
        if (on) dash.push_back(fixedPoint(b));
        break;
      }
      t += remaining;
      const Eigen::Vector2d p = a + (b - a) * (t / length);
      if (on) {
        dash.push_back(fixedPoint(p));
        cv::polylines(image, dash, false, colour, thickness, cv::LINE_AA, kShift);
        dash.clear();
      } else {
        dash = {fixedPoint(p)};
      }
      on = !on;
      phase = 0.0;
    }
  }
  if (on && dash.size() >= 2) cv::polylines(image, dash, false, colour, thickness, cv::LINE_AA, kShift);
}

// The marker's outline as a polygon around `c` (radius r: about the half-width), or empty for a circle or a cross.
std::vector<cv::Point> markerPolygon(PlotMarker marker, const Eigen::Vector2d& c, double r) {
  std::vector<Eigen::Vector2d> v;
  switch (marker) {
    case PlotMarker::kSquare: {
      const double h = 0.88 * r;  // the same area as the circle, about
      v = {{-h, -h}, {h, -h}, {h, h}, {-h, h}};
      break;
    }
    case PlotMarker::kTriangleUp:
      v = {{0, -1.3 * r}, {1.15 * r, 0.75 * r}, {-1.15 * r, 0.75 * r}};
      break;
    case PlotMarker::kTriangleDown:
      v = {{0, 1.3 * r}, {1.15 * r, -0.75 * r}, {-1.15 * r, -0.75 * r}};
      break;
    case PlotMarker::kDiamond:
      v = {{0, -1.25 * r}, {1.05 * r, 0}, {0, 1.25 * r}, {-1.05 * r, 0}};
      break;
    case PlotMarker::kCircle:
    case PlotMarker::kCross:
      return {};
  }
  std::vector<cv::Point> out;
  for (const auto& p : v) out.push_back(fixedPoint(c + p));
  return out;
}

// A marker: the shape filled in `colour` over a white rim, so markers stay apart from lines and each other.
void drawMarker(cv::Mat& image, PlotMarker marker, const Eigen::Vector2d& c, double r, const cv::Scalar& colour, double unit) {
  const double rim = 1.5 * unit;
  if (marker == PlotMarker::kCircle) {
    cv::circle(image, fixedPoint(c), fixedLength(r + rim), kWhite, cv::FILLED, cv::LINE_AA, kShift);
    cv::circle(image, fixedPoint(c), fixedLength(r), colour, cv::FILLED, cv::LINE_AA, kShift);
    return;
  }
  if (marker == PlotMarker::kCross) {
    const double arm = 1.05 * r;
    const int thickness = std::max(2, static_cast<int>(std::lround(0.75 * r)));
    for (const double s : {1.0, -1.0}) {
      cv::line(image, fixedPoint(c + Eigen::Vector2d(-arm, -s * arm)), fixedPoint(c + Eigen::Vector2d(arm, s * arm)), kWhite,
               thickness + static_cast<int>(std::lround(2 * rim)), cv::LINE_AA, kShift);
    }
    for (const double s : {1.0, -1.0}) {
      cv::line(image, fixedPoint(c + Eigen::Vector2d(-arm, -s * arm)), fixedPoint(c + Eigen::Vector2d(arm, s * arm)), colour, thickness,
               cv::LINE_AA, kShift);
    }
    return;
  }
  const std::vector<cv::Point> halo = markerPolygon(marker, c, r + rim * 1.3);
  cv::fillPoly(image, std::vector<std::vector<cv::Point>>{halo}, kWhite, cv::LINE_AA, kShift);
  const std::vector<cv::Point> shape = markerPolygon(marker, c, r);
  cv::fillPoly(image, std::vector<std::vector<cv::Point>>{shape}, colour, cv::LINE_AA, kShift);
}

// A whisker from `low` to `high` (pixel positions on one column) with short caps.
void drawWhisker(cv::Mat& image, const Eigen::Vector2d& low, const Eigen::Vector2d& high, const cv::Scalar& colour, double unit) {
  const int thickness = std::max(1, static_cast<int>(std::lround(1.5 * unit)));
  const Eigen::Vector2d cap(3.5 * unit, 0.0);
  cv::line(image, fixedPoint(low), fixedPoint(high), colour, thickness, cv::LINE_AA, kShift);
  cv::line(image, fixedPoint(low - cap), fixedPoint(low + cap), colour, thickness, cv::LINE_AA, kShift);
  cv::line(image, fixedPoint(high - cap), fixedPoint(high + cap), colour, thickness, cv::LINE_AA, kShift);
}

// Writes `text` turned a quarter counter-clockwise (reading upwards), centred on `centre`.
void writeUpwards(cv::Mat& image, const std::string& text, const Pen& pen, cv::Point centre, const cv::Scalar& colour) {
  const cv::Size size = pen.size(text);
  const int descent = pen.descent();
  cv::Mat flat(size.height + descent + 4, size.width + 4, CV_8UC3, kWhite);
  pen.write(flat, text, {2, size.height + 2}, colour);
  cv::Mat upright;
  cv::rotate(flat, upright, cv::ROTATE_90_COUNTERCLOCKWISE);
  const cv::Rect at(centre.x - upright.cols / 2, centre.y - upright.rows / 2, upright.cols, upright.rows);
  const cv::Rect inside = at & cv::Rect(0, 0, image.cols, image.rows);
  if (inside.empty()) return;
  cv::Mat target = image(inside);
  cv::min(target, upright(cv::Rect(inside.x - at.x, inside.y - at.y, inside.width, inside.height)), target);  // dark text over white
}

}  // namespace

Rgb plotSeriesColour(std::size_t index) { return kPlotPalette[index % std::size(kPlotPalette)]; }

PlotMarker plotSeriesMarker(std::size_t index) { return static_cast<PlotMarker>(index % kMarkerCount); }

Eigen::Vector2d PlotLayout::toPixel(double x, double y) const {
  const double yl = log_y ? std::log10(y) : y;
  const double lo = log_y ? std::log10(y_min) : y_min;
  const double hi = log_y ? std::log10(y_max) : y_max;
  return {plot_left_px + (x - x_min) / (x_max - x_min) * plot_width_px, plot_top_px + (hi - yl) / (hi - lo) * plot_height_px};
}

Eigen::Vector2d PlotLayout::pointPixel(std::size_t series, double x, double y) const {
  const double shift = (static_cast<double>(series) - (static_cast<double>(series_count) - 1.0) / 2.0) * dodge_px;
  return toPixel(x, y) + Eigen::Vector2d(shift, 0.0);
}

Expected<PlotLayout> plotLayout(const PlotSpec& spec, int width_px, int height_px) {
  if (Status s = validate(spec, width_px, height_px); !s.ok()) return s.error();
  const double unit = unitOf(width_px, height_px);
  const auto px = [&](double v) { return static_cast<int>(std::lround(v * unit)); };
  const Pens pens(unit);
  PlotLayout l;
  l.width_px = width_px;
  l.height_px = height_px;
  l.log_y = spec.log_y;
  l.dodge_px = spec.dodge_px;
  l.series_count = spec.series.size();
  const int pad = px(14);
  const int tick_len = px(5);
  const int label_gap = px(7);
  const int text_h = pens.tick.size("0").height;
  const int axis_h = pens.axis.size("Ag").height + pens.axis.descent();

  // Top to bottom: the title band, the plot area, tick labels, the x axis label.
  const int title_band = spec.title.empty() ? pad : pad + pens.title.size("Ag").height + pens.title.descent() + px(12);
  l.plot_top_px = title_band + text_h;  // room for the top y tick label's upper half
  const int below = tick_len + label_gap + text_h + (spec.x_label.empty() ? 0 : px(16) + axis_h) + pad;
  l.plot_height_px = height_px - l.plot_top_px - below;

  // y: the range and ticks, which set how wide the labels on the left are.
  const auto [ylo, yhi] = yRange(spec);
  const int y_count = std::clamp(static_cast<int>(l.plot_height_px / (55.0 * unit)), 2, 10);
  if (spec.log_y) {
    l.y_min = std::pow(10.0, ylo);
    l.y_max = std::pow(10.0, yhi);
    const LogTicks t = logTicks(ylo, yhi, y_count);
    l.y_ticks = t.major;
    l.y_minor_ticks = t.minor;
    for (const double v : l.y_ticks) l.y_tick_labels.push_back(siLabel(v));
  } else {
    l.y_min = ylo;
    l.y_max = yhi;
    double step = 1.0;
    l.y_ticks = niceTicks(ylo, yhi, y_count, &step);
    l.y_tick_labels = linearLabels(l.y_ticks, step);
  }
  int label_w = 0;
  for (const auto& s : l.y_tick_labels) label_w = std::max(label_w, pens.tick.size(s).width);
  const int y_label_band = spec.y_label.empty() ? 0 : axis_h + px(14);
  l.plot_left_px = pad + y_label_band + label_w + label_gap + tick_len;

  // The legend on the right: as wide as its longest entry, at most a third of the picture.
  const LegendMetrics m = legendMetrics(pens.legend, unit);
  int natural = 0;
  for (const auto& s : spec.series) natural = std::max(natural, pens.legend.size(s.name.empty() ? "(unnamed)" : s.name).width);
  const int fixed_w = 2 * m.pad + m.swatch_w + m.gap;
  const int max_w = width_px / 3;
  l.legend_width_px = fixed_w + natural;
  if (!spec.whisker_note.empty() && hasWhiskers(spec)) {
    l.legend_width_px = std::max(l.legend_width_px, 2 * m.pad + pens.legend.size(spec.whisker_note).width);
  }
  l.legend_width_px = std::min(l.legend_width_px, max_w);
  l.legend_left_px = width_px - pad - l.legend_width_px;
  l.legend_top_px = l.plot_top_px;
  l.legend_height_px = legendHeight(legendText(spec, pens.legend, l.legend_width_px - fixed_w, l.legend_width_px - 2 * m.pad), m);
  l.plot_width_px = l.legend_left_px - px(22) - l.plot_left_px;
  if (l.plot_width_px < px(100) || l.plot_height_px < px(80)) {
    return invalidArgument("plot: " + sizeText(width_px, height_px) + " pixels leave no room for the data beside the labels and legend");
  }

  // x: the range, then ticks whose labels do not touch.
  const auto [xlo, xhi] = xRange(spec);
  l.x_min = xlo;
  l.x_max = xhi;
  const auto centres = [&](const std::vector<double>& ticks) {
    std::vector<double> out;
    for (const double t : ticks) out.push_back(l.toPixel(t, l.log_y ? l.y_max : 0.0).x());
    return out;
  };
  const int x_gap = px(14);
  if (!spec.x_ticks.empty()) {
    l.x_ticks = spec.x_ticks;
    std::sort(l.x_ticks.begin(), l.x_ticks.end());
    l.x_ticks.erase(std::unique(l.x_ticks.begin(), l.x_ticks.end()), l.x_ticks.end());
    for (const double t : l.x_ticks) {
      char text[48];
      std::snprintf(text, sizeof(text), "%g", t);
      l.x_tick_labels.push_back(text);
    }
    thinLabels(l.x_tick_labels, centres(l.x_ticks), pens.tick, x_gap);
  } else {
    for (int count = std::clamp(static_cast<int>(l.plot_width_px / (70.0 * unit)), 2, 12); count >= 1; --count) {
      double step = 1.0;
      l.x_ticks = niceTicks(xlo, xhi, count, &step);
      l.x_tick_labels = linearLabels(l.x_ticks, step);
      if (labelsFit(l.x_tick_labels, centres(l.x_ticks), pens.tick, x_gap)) break;
    }
    thinLabels(l.x_tick_labels, centres(l.x_ticks), pens.tick, x_gap);
  }
  return l;
}

Status drawLinePlot(const std::filesystem::path& png, const PlotSpec& spec, int width_px, int height_px) {
  const Expected<PlotLayout> laid = plotLayout(spec, width_px, height_px);
  if (!laid.ok()) return laid.error();
  const PlotLayout& l = *laid;
  const double unit = unitOf(width_px, height_px);
  const auto px = [&](double v) { return static_cast<int>(std::lround(v * unit)); };
  const Pens pens(unit);
  cv::Mat image(height_px, width_px, CV_8UC3, bgr(kPlotBackground));
  const cv::Rect area(l.plot_left_px, l.plot_top_px, l.plot_width_px, l.plot_height_px);
  const int bottom = l.plot_top_px + l.plot_height_px;
  const int right = l.plot_left_px + l.plot_width_px;
  const double left_edge = l.plot_left_px;  // continuous coordinates of the area's edges
  const double right_edge = right;

  // The grid: fainter minor lines, then the lines of labelled ticks.
  const auto row_of = [&](double y) { return l.toPixel(l.x_min, y).y(); };
  const auto col_of = [&](double x) { return l.toPixel(x, l.log_y ? l.y_max : 0.0).x(); };
  for (const double v : l.y_minor_ticks) {
    cv::line(image, fixedPoint({left_edge, row_of(v)}), fixedPoint({right_edge, row_of(v)}), kMinorGridColour, 1, cv::LINE_AA, kShift);
  }
  for (const double v : l.y_ticks) {
    cv::line(image, fixedPoint({left_edge, row_of(v)}), fixedPoint({right_edge, row_of(v)}), kPlotGridColour, 1, cv::LINE_AA, kShift);
  }
  for (const double v : l.x_ticks) {
    cv::line(image, fixedPoint({col_of(v), static_cast<double>(l.plot_top_px)}), fixedPoint({col_of(v), static_cast<double>(bottom)}), kPlotGridColour, 1,
             cv::LINE_AA, kShift);
  }

  // The data, in views of the picture: lines and whiskers clipped to the plot area, markers to a
  // slightly larger one so that a point on the frame shows whole.
  const double radius = 5.0 * unit;
  const int line_px = std::max(1, px(2));
  cv::Mat view = image(area);
  const Eigen::Vector2d origin(l.plot_left_px, l.plot_top_px);
  const int margin = static_cast<int>(std::ceil(radius * 1.5)) + 2;
  const cv::Rect wider = cv::Rect(area.x - margin, area.y - margin, area.width + 2 * margin, area.height + 2 * margin) & cv::Rect(0, 0, width_px, height_px);
  cv::Mat marker_view = image(wider);
  const Eigen::Vector2d marker_origin(wider.x, wider.y);
  for (std::size_t i = 0; i < spec.series.size(); ++i) {
    const PlotSeries& s = spec.series[i];
    if (s.y_low.empty() || s.y_high.empty()) continue;
    for (std::size_t k = 0; k < s.x.size(); ++k) {
      if (!std::isfinite(s.y_low[k]) || !std::isfinite(s.y_high[k])) continue;
      drawWhisker(view, l.pointPixel(i, s.x[k], s.y_low[k]) - origin, l.pointPixel(i, s.x[k], s.y_high[k]) - origin, bgr(plotSeriesColour(i)), unit);
    }
  }
  for (std::size_t i = 0; i < spec.series.size(); ++i) {
    const PlotSeries& s = spec.series[i];
    std::vector<Eigen::Vector2d> run;  // consecutive points with a y; a NaN ends it
    for (std::size_t k = 0; k <= s.x.size(); ++k) {
      if (k < s.x.size() && std::isfinite(s.y[k])) {
        run.push_back(l.pointPixel(i, s.x[k], s.y[k]) - origin);
        continue;
      }
      drawLine(view, run, bgr(plotSeriesColour(i)), line_px, s.dashed, unit);
      run.clear();
    }
  }
  for (std::size_t i = 0; i < spec.series.size(); ++i) {
    const PlotSeries& s = spec.series[i];
    for (std::size_t k = 0; k < s.x.size(); ++k) {
      if (!std::isfinite(s.y[k])) continue;
      const Eigen::Vector2d at = l.pointPixel(i, s.x[k], s.y[k]);
      if (at.x() < left_edge - 1 || at.x() > right_edge + 1 || at.y() < l.plot_top_px - 1 || at.y() > bottom + 1) continue;  // out of range
      drawMarker(marker_view, plotSeriesMarker(i), at - marker_origin, radius, bgr(plotSeriesColour(i)), unit);
    }
  }
  cv::rectangle(image, cv::Point(area.x - 1, area.y - 1), cv::Point(right, bottom), kFrameColour, 1);

  // Ticks and their labels, then the axis labels.
  const int tick_len = px(5);
  const int label_gap = px(7);
  const int text_h = pens.tick.size("0").height;
  for (std::size_t i = 0; i < l.x_ticks.size(); ++i) {
    const int col = static_cast<int>(std::floor(col_of(l.x_ticks[i])));
    cv::line(image, {col, bottom}, {col, bottom + tick_len}, kFrameColour, 1);
    const std::string& text = l.x_tick_labels[i];
    if (text.empty()) continue;
    pens.tick.write(image, text, {col - pens.tick.size(text).width / 2, bottom + tick_len + label_gap + text_h}, kTextColour);
  }
  for (std::size_t i = 0; i < l.y_ticks.size(); ++i) {
    const int row = static_cast<int>(std::floor(row_of(l.y_ticks[i])));
    cv::line(image, {l.plot_left_px - 1 - tick_len, row}, {l.plot_left_px - 1, row}, kFrameColour, 1);
    const std::string& text = l.y_tick_labels[i];
    pens.tick.write(image, text, {l.plot_left_px - 1 - tick_len - label_gap - pens.tick.size(text).width, row + text_h / 2}, kTextColour);
  }
  for (const double v : l.y_minor_ticks) {
    const int row = static_cast<int>(std::floor(row_of(v)));
    cv::line(image, {l.plot_left_px - 1 - tick_len / 2, row}, {l.plot_left_px - 1, row}, kFrameColour, 1);
  }
  if (!spec.x_label.empty()) {
    const Pen pen = pens.axis.shrunkToFit(spec.x_label, l.plot_width_px + l.plot_left_px, 0.3 * unit);
    const cv::Size size = pen.size(spec.x_label);
    const int x = std::max(px(4), l.plot_left_px + l.plot_width_px / 2 - size.width / 2);
    pen.write(image, spec.x_label, {x, bottom + tick_len + label_gap + text_h + px(16) + size.height}, kTextColour);
  }
  if (!spec.y_label.empty()) {
    const Pen pen = pens.axis.shrunkToFit(spec.y_label, l.plot_height_px + px(40), 0.3 * unit);
    const int band = pens.axis.size("Ag").height + pens.axis.descent();
    writeUpwards(image, spec.y_label, pen, {px(14) + band / 2, l.plot_top_px + l.plot_height_px / 2}, kTextColour);
  }

  // The legend: per series a sample of its line, marker (and whisker), then its name.
  const LegendMetrics m = legendMetrics(pens.legend, unit);
  const int text_left = l.legend_left_px + m.pad + m.swatch_w + m.gap;
  const LegendText legend = legendText(spec, pens.legend, l.legend_left_px + l.legend_width_px - m.pad - text_left, l.legend_width_px - 2 * m.pad);
  const cv::Rect panel(l.legend_left_px, l.legend_top_px, l.legend_width_px, l.legend_height_px);
  cv::rectangle(image, panel, kLegendFillColour, cv::FILLED);
  cv::rectangle(image, panel, kLegendFrameColour, 1);
  const int cap_h = pens.legend.size("A").height;
  int y = panel.y + m.pad;
  for (std::size_t i = 0; i < spec.series.size(); ++i) {
    const PlotSeries& s = spec.series[i];
    const double mid = y + m.line_h / 2.0;
    const Eigen::Vector2d a(l.legend_left_px + m.pad, mid);
    const Eigen::Vector2d b(l.legend_left_px + m.pad + m.swatch_w, mid);
    const cv::Scalar colour = bgr(plotSeriesColour(i));
    if (!s.y_low.empty() && !s.y_high.empty()) {
      const Eigen::Vector2d half(0.0, std::min(m.line_h * 0.45, 9.0 * unit));
      drawWhisker(image, (a + b) / 2 + half, (a + b) / 2 - half, colour, unit);
    }
    drawLine(image, {a, b}, colour, line_px, s.dashed, unit * 0.82);  // a shorter dash: two whole dashes in the sample
    drawMarker(image, plotSeriesMarker(i), (a + b) / 2, radius, colour, unit);
    int ty = static_cast<int>(std::lround(mid + cap_h / 2.0));
    for (const auto& line : legend.entries[i]) {
      pens.legend.write(image, line, {text_left, ty}, kTextColour);
      ty += m.line_h;
    }
    y += static_cast<int>(legend.entries[i].size()) * m.line_h + m.entry_gap;
  }
  if (!legend.note.empty()) {
    cv::line(image, {panel.x + m.pad, y}, {panel.x + panel.width - m.pad, y}, kLegendFrameColour, 1);
    int ty = static_cast<int>(std::lround(y + m.entry_gap + m.line_h / 2.0 + cap_h / 2.0));
    for (const auto& line : legend.note) {
      pens.legend.write(image, line, {panel.x + m.pad, ty}, kMutedTextColour);
      ty += m.line_h;
    }
  }

  // The title, centred over the plot area where it fits, shrunk until it fits the picture.
  if (!spec.title.empty()) {
    const int room = width_px - 2 * px(14);
    const Pen pen = pens.title.shrunkToFit(spec.title, room, 0.3 * unit);
    const cv::Size size = pen.size(spec.title);
    const int x = std::clamp(l.plot_left_px + l.plot_width_px / 2 - size.width / 2, px(14), std::max(px(14), width_px - px(14) - size.width));
    pen.write(image, spec.title, {x, px(14) + pens.title.size("Ag").height}, kTextColour);
  }

  return drawing::writePng(png, image, "plot");
}

}  // namespace fogmap::pictures
