// Line charts (pictures/plot) read back as pixels: points land where the layout says in their
// series' colours, decades are equally spaced on a log axis, ticks are nice numbers, gaps and dashes
// show, the legend lies beside the data, errors name what is wrong, the same input gives the same
// bytes; and the MAD-C paper's kinds of figures, drawn for a person to look at (FOGMAP_PLOT_DIR).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "tests/support/scratch_dir.hpp"
#include "pictures/plot.hpp"

namespace fogmap::pictures {
namespace {

namespace fs = std::filesystem;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

using test_support::readFile;
using test_support::ScratchDir;

// The pixel that holds the continuous position `at`.
cv::Point pixelAt(const Eigen::Vector2d& at) { return {static_cast<int>(std::floor(at.x())), static_cast<int>(std::floor(at.y()))}; }

Rgb rgbAt(const cv::Mat& image, cv::Point p) {
  const cv::Vec3b v = image.at<cv::Vec3b>(p.y, p.x);
  return {v[2], v[1], v[0]};
}

bool colourAt(const cv::Mat& image, cv::Point p, const Rgb& want, int tolerance = 12) {
  const Rgb got = rgbAt(image, p);
  return std::abs(got.r - want.r) <= tolerance && std::abs(got.g - want.g) <= tolerance && std::abs(got.b - want.b) <= tolerance;
}

cv::Mat drawAndRead(const fs::path& png, const PlotSpec& spec, int width = 900, int height = 560) {
  const Status s = drawLinePlot(png, spec, width, height);
  EXPECT_TRUE(s.ok()) << s.error().message;
  return cv::imread(png.string(), cv::IMREAD_COLOR);
}

// Two series far apart: a rising solid one and a falling dashed one, on x in [0, 10], y in [0, 100].
PlotSpec twoSeries() {
  PlotSpec spec;
  spec.title = "two series";
  spec.x_label = "x (units)";
  spec.y_label = "y (units)";
  spec.series = {{"rising", {0, 5, 10}, {10, 50, 90}, {}, {}, false}, {"falling", {0, 5, 10}, {90, 60, 20}, {}, {}, true}};
  return spec;
}

TEST(Plot, PointsLandWhereTheLayoutSaysInTheirSeriesColours) {
  ScratchDir dir("points");
  const PlotSpec spec = twoSeries();
  const cv::Mat image = drawAndRead(dir.path() / "two.png", spec);
  ASSERT_FALSE(image.empty());
  const auto layout = plotLayout(spec);
  ASSERT_TRUE(layout.ok()) << layout.error().message;
  EXPECT_EQ(image.cols, layout->width_px);
  EXPECT_EQ(image.rows, layout->height_px);
  EXPECT_NE(plotSeriesColour(0), plotSeriesColour(1));
  EXPECT_NE(plotSeriesMarker(0), plotSeriesMarker(1));
  for (std::size_t i = 0; i < spec.series.size(); ++i) {
    const PlotSeries& s = spec.series[i];
    for (std::size_t k = 0; k < s.x.size(); ++k) {
      EXPECT_TRUE(colourAt(image, pixelAt(layout->toPixel(s.x[k], s.y[k])), plotSeriesColour(i))) << s.name << " point " << k;
    }
  }
  // x right, y up: (0, 10) is at the lower left of (10, 90).
  const Eigen::Vector2d low = layout->toPixel(0, 10);
  const Eigen::Vector2d high = layout->toPixel(10, 90);
  EXPECT_LT(low.x(), high.x());
  EXPECT_GT(low.y(), high.y());
  // The points lie inside the plot area, and away from the lines there is only the background.
  EXPECT_GE(low.x(), layout->plot_left_px);
  EXPECT_LE(high.x(), layout->plot_left_px + layout->plot_width_px);
  EXPECT_TRUE(colourAt(image, pixelAt(layout->toPixel(7.7, 86.3)), kPlotBackground, 0));
  // The solid line between its points: on the segment from (0, 10) to (5, 50).
  EXPECT_TRUE(colourAt(image, pixelAt(layout->toPixel(2.5, 30)), plotSeriesColour(0), 40));
}

TEST(Plot, ALogAxisSpacesDecadesEqually) {
  ScratchDir dir("log");
  PlotSpec spec;
  spec.log_y = true;
  spec.y_label = "bytes per frame";
  spec.series = {{"decades", {1, 2, 3}, {1, 10, 100}, {}, {}, false}};
  const auto layout = plotLayout(spec);
  ASSERT_TRUE(layout.ok()) << layout.error().message;
  const double one = layout->toPixel(1, 1).y();
  const double ten = layout->toPixel(1, 10).y();
  const double hundred = layout->toPixel(1, 100).y();
  EXPECT_GT(one - ten, 50.0) << "10 lies well above 1";
  EXPECT_NEAR(one - ten, ten - hundred, 1e-9);
  EXPECT_NEAR(layout->toPixel(1, std::sqrt(10.0)).y(), (one + ten) / 2.0, 1e-9) << "sqrt(10) halfway between 1 and 10";
  // The labelled ticks are the decades, with their labels; 2..9 x 10^k are unlabelled minor ticks.
  EXPECT_EQ(layout->y_ticks, (std::vector<double>{1, 10, 100}));
  EXPECT_EQ(layout->y_tick_labels, (std::vector<std::string>{"1", "10", "100"}));
  const auto minor_in_range = std::count_if(layout->y_minor_ticks.begin(), layout->y_minor_ticks.end(), [](double v) { return v > 1 && v < 100; });
  EXPECT_EQ(minor_in_range, 16) << "2..9 between 1 and 10, and 20..90 between 10 and 100";
  // The drawn points are where the layout says.
  const cv::Mat image = drawAndRead(dir.path() / "log.png", spec);
  ASSERT_FALSE(image.empty());
  for (std::size_t k = 0; k < 3; ++k) {
    EXPECT_TRUE(colourAt(image, pixelAt(layout->toPixel(spec.series[0].x[k], spec.series[0].y[k])), plotSeriesColour(0))) << k;
  }
}

TEST(Plot, ManyDecadesAreLabelledShortly) {
  PlotSpec spec;
  spec.log_y = true;
  spec.series = {{"bytes", {2, 7}, {1, 2e6}, {}, {}, false}};
  const auto layout = plotLayout(spec);
  ASSERT_TRUE(layout.ok()) << layout.error().message;
  EXPECT_EQ(layout->y_tick_labels, (std::vector<std::string>{"1", "10", "100", "1k", "10k", "100k", "1M"}));
}

TEST(Plot, LinearTicksAreNiceNumbersAndExplicitTicksAreKept) {
  PlotSpec spec;
  spec.series = {{"alpha", {0.2, 1.0, 3.0}, {0.13, 0.5, 0.97}, {}, {}, false}};
  auto layout = plotLayout(spec);
  ASSERT_TRUE(layout.ok()) << layout.error().message;
  ASSERT_GE(layout->x_ticks.size(), 3U);
  ASSERT_GE(layout->y_ticks.size(), 3U);
  for (const auto* ticks : {&layout->x_ticks, &layout->y_ticks}) {
    const double step = (*ticks)[1] - (*ticks)[0];
    const double mantissa = step / std::pow(10.0, std::floor(std::log10(step) + 1e-9));
    EXPECT_TRUE(std::abs(mantissa - 1) < 1e-6 || std::abs(mantissa - 2) < 1e-6 || std::abs(mantissa - 5) < 1e-6) << "step " << step;
    for (const double t : *ticks) EXPECT_NEAR(std::remainder(t, step), 0.0, 1e-9) << "tick " << t << " on a multiple of " << step;
  }
  EXPECT_LE(layout->x_min, 0.2);
  EXPECT_GE(layout->x_max, 3.0);
  EXPECT_EQ(layout->x_tick_labels.front().find('.') != std::string::npos, layout->x_ticks[1] - layout->x_ticks[0] < 1.0);
  // Explicit ticks and y range are used as given.
  spec.x_ticks = {7, 2, 3, 5};
  spec.y_min = 0.0;
  spec.y_max = 1.0;
  layout = plotLayout(spec);
  ASSERT_TRUE(layout.ok()) << layout.error().message;
  EXPECT_EQ(layout->x_ticks, (std::vector<double>{2, 3, 5, 7}));
  EXPECT_EQ(layout->x_tick_labels, (std::vector<std::string>{"2", "3", "5", "7"}));
  EXPECT_DOUBLE_EQ(layout->y_min, 0.0);
  EXPECT_DOUBLE_EQ(layout->y_max, 1.0);
  EXPECT_DOUBLE_EQ(layout->toPixel(1.0, 0.0).y(), layout->plot_top_px + layout->plot_height_px);
  EXPECT_DOUBLE_EQ(layout->toPixel(1.0, 1.0).y(), layout->plot_top_px);
}

TEST(Plot, ANaNIsAGapAndADashedLineHasGaps) {
  ScratchDir dir("gaps");
  PlotSpec spec;
  spec.y_min = 0.0;
  spec.y_max = 10.0;
  // Heights between the grid lines (every 2).
  spec.series = {{"gap", {0, 1, 2}, {3.3, kNaN, 3.3}, {}, {}, false},
                 {"dashed", {0, 2}, {5.3, 5.3}, {}, {}, true},
                 {"solid", {0, 2}, {7.3, 7.3}, {}, {}, false}};
  const cv::Mat image = drawAndRead(dir.path() / "gaps.png", spec);
  ASSERT_FALSE(image.empty());
  const auto layout = plotLayout(spec);
  ASSERT_TRUE(layout.ok());
  // Along each horizontal line from x = 0.2 to 1.8 (clear of the markers): how many pixels are in
  // the series' colour, and how many are the bare background.
  struct Count {
    int inked = 0;
    int bare = 0;
    int samples = 0;
  };
  const auto along = [&](double y, std::size_t series) {
    Count c;
    const int from = pixelAt(layout->toPixel(0.2, y)).x;
    const int to = pixelAt(layout->toPixel(1.8, y)).x;
    const int row = pixelAt(layout->toPixel(0.2, y)).y;
    for (int col = from; col <= to; ++col, ++c.samples) {
      c.inked += colourAt(image, {col, row}, plotSeriesColour(series), 40) ? 1 : 0;
      c.bare += colourAt(image, {col, row}, kPlotBackground, 0) ? 1 : 0;
    }
    return c;
  };
  const Count gap = along(3.3, 0);
  EXPECT_EQ(gap.inked, 0) << "no line across the NaN";
  EXPECT_TRUE(colourAt(image, pixelAt(layout->toPixel(0, 3.3)), plotSeriesColour(0))) << "but both points";
  EXPECT_TRUE(colourAt(image, pixelAt(layout->toPixel(2, 3.3)), plotSeriesColour(0)));
  const Count dashed = along(5.3, 1);
  EXPECT_GT(dashed.inked, dashed.samples / 3) << "dashes";
  EXPECT_GT(dashed.bare, dashed.samples / 16) << "and gaps between them (the bare middles of the gaps)";
  EXPECT_LT(dashed.inked, dashed.samples * 9 / 10);
  const Count solid = along(7.3, 2);
  EXPECT_EQ(solid.inked, solid.samples);
  EXPECT_EQ(solid.bare, 0);
}

TEST(Plot, WhiskersSpanTheirRange) {
  ScratchDir dir("whiskers");
  PlotSpec spec;
  spec.y_min = 0.0;
  spec.y_max = 1.0;
  spec.series = {{"rand index", {2, 3}, {0.5, 0.6}, {0.2, kNaN}, {0.9, kNaN}, false}};
  const cv::Mat image = drawAndRead(dir.path() / "whiskers.png", spec);
  ASSERT_FALSE(image.empty());
  const auto layout = plotLayout(spec);
  ASSERT_TRUE(layout.ok());
  const Rgb colour = plotSeriesColour(0);
  EXPECT_TRUE(colourAt(image, pixelAt(layout->toPixel(2, 0.25)), colour, 40)) << "inside the whisker";
  EXPECT_TRUE(colourAt(image, pixelAt(layout->toPixel(2, 0.85)), colour, 40));
  EXPECT_TRUE(colourAt(image, pixelAt(layout->toPixel(2, 0.95)), kPlotBackground, 25)) << "beyond its end";
  EXPECT_TRUE(colourAt(image, pixelAt(layout->toPixel(3, 0.85)), kPlotBackground, 25)) << "a NaN range: no whisker";
}

TEST(Plot, DodgedSeriesStandApartAroundTheirX) {
  ScratchDir dir("dodge");
  PlotSpec spec;
  spec.dodge_px = 8.0;
  spec.y_min = 0.0;
  spec.y_max = 1.0;
  for (int i = 0; i < 3; ++i) spec.series.push_back({"s" + std::to_string(i), {1, 2}, {0.5, 0.5}, {0.2, 0.2}, {0.8, 0.8}, false});
  const auto layout = plotLayout(spec);
  ASSERT_TRUE(layout.ok()) << layout.error().message;
  // Three series: the middle one at its x, the others 8 pixels to either side.
  EXPECT_NEAR(layout->pointPixel(0, 1, 0.5).x(), layout->toPixel(1, 0.5).x() - 8.0, 1e-9);
  EXPECT_NEAR(layout->pointPixel(1, 1, 0.5).x(), layout->toPixel(1, 0.5).x(), 1e-9);
  EXPECT_NEAR(layout->pointPixel(2, 1, 0.5).x(), layout->toPixel(1, 0.5).x() + 8.0, 1e-9);
  const cv::Mat image = drawAndRead(dir.path() / "dodge.png", spec);
  ASSERT_FALSE(image.empty());
  // Each series' whisker stands on its own column, in its own colour.
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_TRUE(colourAt(image, pixelAt(layout->pointPixel(i, 1, 0.3)), plotSeriesColour(i), 40)) << "whisker of series " << i;
  }
}

TEST(Plot, TheLegendLiesBesideTheDataAndShowsEverySeries) {
  ScratchDir dir("legend");
  const PlotSpec spec = twoSeries();
  const cv::Mat image = drawAndRead(dir.path() / "legend.png", spec);
  ASSERT_FALSE(image.empty());
  const auto l = plotLayout(spec);
  ASSERT_TRUE(l.ok());
  const cv::Rect area(l->plot_left_px, l->plot_top_px, l->plot_width_px, l->plot_height_px);
  const cv::Rect legend(l->legend_left_px, l->legend_top_px, l->legend_width_px, l->legend_height_px);
  EXPECT_TRUE((area & legend).empty());
  EXPECT_LE(legend.x + legend.width, image.cols);
  EXPECT_LE(legend.y + legend.height, image.rows);
  for (std::size_t i = 0; i < spec.series.size(); ++i) {
    cv::Mat mask;
    const Rgb c = plotSeriesColour(i);
    cv::inRange(image(legend), cv::Scalar(c.b, c.g, c.r) - cv::Scalar::all(10), cv::Scalar(c.b, c.g, c.r) + cv::Scalar::all(10), mask);
    EXPECT_GT(cv::countNonZero(mask), 30) << "the sample of " << spec.series[i].name;
  }
  const auto dark = [&](cv::Rect r) {
    cv::Mat grey;
    cv::cvtColor(image(r), grey, cv::COLOR_BGR2GRAY);
    return cv::countNonZero(grey < 120);
  };
  EXPECT_GT(dark(legend), 100) << "the names";
  EXPECT_GT(dark({0, 0, image.cols, l->plot_top_px - 8}), 100) << "the title";
  EXPECT_GT(dark({0, area.y, area.x - 2, area.height}), 100) << "y tick labels and label";
  EXPECT_GT(dark({area.x, area.y + area.height + 2, area.width, image.rows - area.y - area.height - 2}), 100) << "x tick labels and label";
}

TEST(Plot, BadInputIsRejectedAndNothingIsWritten) {
  ScratchDir dir("bad");
  const fs::path png = dir.path() / "bad.png";
  const auto rejected = [&](const PlotSpec& spec, const std::string& mentions) {
    const Status s = drawLinePlot(png, spec);
    if (s.ok()) return ::testing::AssertionFailure() << "accepted";
    if (s.error().code != ErrorCode::kInvalidArgument) return ::testing::AssertionFailure() << "code " << errorCodeName(s.error().code);
    if (s.error().message.find(mentions) == std::string::npos) return ::testing::AssertionFailure() << "message: " << s.error().message;
    if (fs::exists(png)) return ::testing::AssertionFailure() << "wrote " << png;
    return ::testing::AssertionSuccess();
  };
  PlotSpec none;
  EXPECT_TRUE(rejected(none, "no series"));
  PlotSpec mismatch = twoSeries();
  mismatch.series[1].y.pop_back();
  EXPECT_TRUE(rejected(mismatch, "series 1 ('falling') has 3 x values but 2 y values"));
  PlotSpec whiskers = twoSeries();
  whiskers.series[0].y_low = {1, 2};
  whiskers.series[0].y_high = {1, 2, 3};
  EXPECT_TRUE(rejected(whiskers, "y_low"));
  PlotSpec log_zero = twoSeries();
  log_zero.log_y = true;
  log_zero.series[0].y[1] = 0.0;
  EXPECT_TRUE(rejected(log_zero, "log axis"));
  PlotSpec log_low = twoSeries();
  log_low.log_y = true;
  log_low.series[1].y_low = {1, -1, 1};
  log_low.series[1].y_high = {2, 2, 2};
  EXPECT_TRUE(rejected(log_low, "log axis"));
  PlotSpec log_bound = twoSeries();
  log_bound.log_y = true;
  log_bound.y_min = 0.0;
  EXPECT_TRUE(rejected(log_bound, "positive"));
  PlotSpec all_nan;
  all_nan.series = {{"a", {1, 2}, {kNaN, kNaN}, {}, {}, false}, {"b", {}, {}, {}, {}, false}};
  EXPECT_TRUE(rejected(all_nan, "no series has a finite y"));
  PlotSpec infinite = twoSeries();
  infinite.series[0].y[2] = std::numeric_limits<double>::infinity();
  EXPECT_TRUE(rejected(infinite, "infinite"));
  PlotSpec x_nan = twoSeries();
  x_nan.series[0].x[0] = kNaN;
  EXPECT_TRUE(rejected(x_nan, "non-finite x"));
  PlotSpec inverted = twoSeries();
  inverted.y_min = 5.0;
  inverted.y_max = 5.0;
  EXPECT_TRUE(rejected(inverted, "y_min must be less than y_max"));
  PlotSpec dodge = twoSeries();
  dodge.dodge_px = -1.0;
  EXPECT_TRUE(rejected(dodge, "dodge_px"));
  const Status tiny = drawLinePlot(png, twoSeries(), 100, 100);
  ASSERT_FALSE(tiny.ok());
  EXPECT_EQ(tiny.error().code, ErrorCode::kInvalidArgument);
  EXPECT_FALSE(fs::exists(png));
}

TEST(Plot, OnePointAndAFlatSeriesStillDraw) {
  ScratchDir dir("degenerate");
  PlotSpec one;
  one.series = {{"one point", {3}, {42}, {}, {}, false}};
  auto layout = plotLayout(one);
  ASSERT_TRUE(layout.ok()) << layout.error().message;
  EXPECT_LT(layout->x_min, 3.0);
  EXPECT_GT(layout->x_max, 3.0);
  EXPECT_LT(layout->y_min, 42.0);
  EXPECT_GT(layout->y_max, 42.0);
  EXPECT_GE(layout->x_ticks.size(), 2U);
  EXPECT_GE(layout->y_ticks.size(), 2U);
  cv::Mat image = drawAndRead(dir.path() / "one.png", one);
  ASSERT_FALSE(image.empty());
  EXPECT_TRUE(colourAt(image, pixelAt(layout->toPixel(3, 42)), plotSeriesColour(0)));

  PlotSpec flat;
  flat.log_y = true;
  flat.series = {{"flat", {1, 2, 3}, {5, 5, 5}, {}, {}, false}, {"zero-free gaps", {1, 2}, {kNaN, 5}, {}, {}, true}};
  layout = plotLayout(flat);
  ASSERT_TRUE(layout.ok()) << layout.error().message;
  EXPECT_LT(layout->y_min, 5.0);
  EXPECT_GT(layout->y_max, 5.0);
  EXPECT_GE(layout->y_ticks.size(), 2U);
  image = drawAndRead(dir.path() / "flat.png", flat);
  ASSERT_FALSE(image.empty());
  EXPECT_TRUE(colourAt(image, pixelAt(layout->toPixel(1, 5)), plotSeriesColour(0)));

  PlotSpec zero;
  zero.series = {{"zeros", {0, 1}, {0, 0}, {}, {}, false}};
  layout = plotLayout(zero);
  ASSERT_TRUE(layout.ok()) << layout.error().message;
  EXPECT_LT(layout->y_min, 0.0);
  EXPECT_GT(layout->y_max, 0.0);
}

TEST(Plot, TheSameInputGivesTheSameBytes) {
  ScratchDir dir("same");
  PlotSpec spec = twoSeries();
  ASSERT_TRUE(drawLinePlot(dir.path() / "one.png", spec).ok());
  ASSERT_TRUE(drawLinePlot(dir.path() / "two.png", spec).ok());
  const std::string one = readFile(dir.path() / "one.png");
  EXPECT_GT(one.size(), 1000U);
  EXPECT_EQ(one, readFile(dir.path() / "two.png"));
  spec.series[0].y[1] = 55;
  ASSERT_TRUE(drawLinePlot(dir.path() / "three.png", spec).ok());
  EXPECT_NE(one, readFile(dir.path() / "three.png")) << "a moved point changes the picture";
}

TEST(Plot, AnUnwritablePathIsAnErrorThatNamesIt) {
  const fs::path png = "/nonexistent-plot-dir/deeper/chart.png";
  const Status s = drawLinePlot(png, twoSeries());
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::kIo);
  EXPECT_NE(s.error().message.find(png.string()), std::string::npos) << s.error().message;
}

// The paper's kinds of figures, with made-up numbers of a plausible shape (no run behind them), for a
// person to look at: into FOGMAP_PLOT_DIR if set, else a scratch directory.
class PlotExamples : public ::testing::Test {
 protected:
  void draw(const std::string& file, const PlotSpec& spec) {
    const fs::path dir = test_support::outputDir("FOGMAP_PLOT_DIR", scratch_);
    const Status s = drawLinePlot(dir / file, spec);
    ASSERT_TRUE(s.ok()) << s.error().message;
    const cv::Mat image = cv::imread((dir / file).string(), cv::IMREAD_COLOR);
    ASSERT_FALSE(image.empty());
    const auto layout = plotLayout(spec);
    ASSERT_TRUE(layout.ok());
    for (std::size_t i = 0; i < spec.series.size(); ++i) {
      const PlotSeries& series = spec.series[i];
      const std::size_t k = series.x.size() - 1;  // the last point is on top of earlier lines
      EXPECT_TRUE(colourAt(image, pixelAt(layout->pointPixel(i, series.x[k], series.y[k])), plotSeriesColour(i), 40)) << series.name;
    }
    std::printf("line chart: %s\n", (dir / file).c_str());
  }

 private:
  ScratchDir scratch_{"examples"};
};

std::vector<double> alphas() {
  std::vector<double> out;
  for (int i = 2; i <= 30; i += 2) out.push_back(i / 10.0);
  return out;
}

TEST_F(PlotExamples, PrecisionAndRecallAgainstAlphaWithAndWithoutAura) {
  PlotSpec spec;
  spec.title = "Precision and recall against alpha (illustrative numbers)";
  spec.x_label = "alpha (confidence step)";
  spec.y_label = "precision, recall";
  spec.y_min = 0.0;
  spec.y_max = 1.0;
  PlotSeries precision{"precision, no aura", {}, {}, {}, {}, false};
  PlotSeries precision_aura{"precision, aura", {}, {}, {}, {}, true};
  PlotSeries recall{"recall, no aura", {}, {}, {}, {}, false};
  PlotSeries recall_aura{"recall, aura", {}, {}, {}, {}, true};
  for (const double a : alphas()) {
    for (auto* s : {&precision, &precision_aura, &recall, &recall_aura}) s->x.push_back(a);
    precision.y.push_back(0.55 + 0.38 * (1.0 - std::exp(-1.6 * a)));
    precision_aura.y.push_back(0.62 + 0.35 * (1.0 - std::exp(-1.9 * a)));
    recall.y.push_back(0.93 - 0.30 * (1.0 - std::exp(-0.9 * a)));
    recall_aura.y.push_back(0.95 - 0.18 * (1.0 - std::exp(-0.9 * a)));
  }
  spec.series = {precision, precision_aura, recall, recall_aura};
  draw("precision-recall-vs-alpha.png", spec);
}

TEST_F(PlotExamples, BytesPerFrameAgainstLidarsOnALogAxis) {
  PlotSpec spec;
  spec.title = "Traffic per frame: MAD-C maps against raw point clouds (illustrative numbers)";
  spec.x_label = "LiDARs";
  spec.y_label = "bytes per frame";
  spec.log_y = true;
  spec.x_ticks = {2, 3, 5, 7};
  spec.whisker_note = "bars: min to max over frames";
  const std::vector<double> lidars = {2, 3, 5, 7};
  PlotSeries madc{"MAD-C (ellipsoid maps)", lidars, {}, {}, {}, false};
  PlotSeries baseline{"baseline (raw points)", lidars, {}, {}, {}, true};
  for (const double n : lidars) {
    madc.y.push_back(2400.0 * n);
    madc.y_low.push_back(1700.0 * n);
    madc.y_high.push_back(3300.0 * n);
    baseline.y.push_back(1.9e6 * n);
    baseline.y_low.push_back(1.7e6 * n);
    baseline.y_high.push_back(2.1e6 * n);
  }
  spec.series = {madc, baseline};
  draw("bytes-per-frame-vs-lidars.png", spec);
}

TEST_F(PlotExamples, RandIndexAgainstAlphaForTwoToSevenLidarsWithMinMaxWhiskers) {
  PlotSpec spec;
  spec.title = "Rand index of the global map against alpha (illustrative numbers)";
  spec.x_label = "alpha (confidence step)";
  spec.y_label = "Rand index";
  spec.whisker_note = "bars: min to max over 5 seeds";
  spec.dodge_px = 5.0;  // four whiskers at each alpha, side by side
  const std::vector<int> lidars = {2, 3, 5, 7};
  for (const int n : lidars) {
    PlotSeries s{std::to_string(n) + " LiDARs", {}, {}, {}, {}, false};
    std::uint32_t state = 1234U + static_cast<std::uint32_t>(n);
    const auto jitter = [&state] {
      state = state * 1664525U + 1013904223U;  // a fixed linear congruential sequence
      return ((state >> 8) % 1000U) / 1000.0;
    };
    for (const double a : alphas()) {
      const double mean = 0.80 + 0.02 * n - 0.05 * std::pow(a - 1.3 - 0.05 * n, 2.0);
      s.x.push_back(a);
      s.y.push_back(mean);
      s.y_low.push_back(mean - 0.01 - 0.02 * jitter());
      s.y_high.push_back(mean + 0.01 + 0.02 * jitter());
    }
    spec.series.push_back(std::move(s));
  }
  draw("rand-index-vs-alpha.png", spec);
}

}  // namespace
}  // namespace fogmap::pictures
