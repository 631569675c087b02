#pragma once
// Line charts a person can read, as in the MAD-C paper's figures: series of (x, y) points joined by
// lines with a marker at each point, optional whiskers (a range per point), axes with nice ticks
// (1, 2, 5 x 10^k; decades on a log y axis), axis labels that carry units, a title, and a legend.
// A pure drawing unit (PNG through OpenCV): no sockets, no file but the one it writes.
//
// The picture: a title band on top, then the framed plot area with a light grid, tick labels on its
// left and bottom edges and the axis labels beyond them, and the legend in a panel on its right, so
// no text lies on the data.
#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/base/status.hpp"
#include "pictures/birdseye.hpp"  // Rgb: one colour type for fogctl's pictures

namespace fogmap::pictures {

struct PlotSeries {
  std::string name;                   // its legend entry
  std::vector<double> x;              // finite; points are joined in this order
  std::vector<double> y;              // as many as x; NaN: no point there, a gap in the line
  std::vector<double> y_low, y_high;  // empty, or as many as x: a whisker from y_low to y_high at each point (NaN: none)
  bool dashed = false;
};

struct PlotSpec {
  std::string title;
  std::string x_label;  // with units, e.g. "alpha (confidence step)"
  std::string y_label;  // e.g. "bytes per frame"
  bool log_y = false;   // a log y axis: decades labelled 1, 10, 100, 1k, ...; every value must be positive
  std::optional<double> y_min, y_max;  // the y range shown; else from the data (whiskers too) with a margin
  std::vector<double> x_ticks;         // explicit x ticks (e.g. 2, 3, 5, 7 LiDARs); else nice ticks
  std::string whisker_note;            // what the whiskers mean, e.g. "bars: min to max of 5 runs" (in the legend)
  double dodge_px = 0.0;  // in [0, 40]: series i's points sit (i - (n - 1) / 2) * dodge_px pixels right of their x,
                          // so that whiskers of series at the same x stand apart (0: all at their x)
  std::vector<PlotSeries> series;
};

// Series i is drawn in colour i % 7 and with marker i % 6, so up to 42 series differ in colour or
// shape. The colours are Okabe and Ito's colour-blind-safe set (without its yellow, too faint on white).
enum class PlotMarker { kCircle, kSquare, kTriangleUp, kDiamond, kTriangleDown, kCross };
inline constexpr Rgb kPlotBackground{255, 255, 255};
inline constexpr Rgb kPlotPalette[] = {{0, 114, 178},   {213, 94, 0},    {0, 158, 115}, {204, 121, 167},
                                       {230, 159, 0},   {86, 180, 233},  {0, 0, 0}};
Rgb plotSeriesColour(std::size_t index);
PlotMarker plotSeriesMarker(std::size_t index);

// Where the parts of a chart lie, in pixels from the top-left corner, and the ranges and ticks shown.
struct PlotLayout {
  int width_px = 0;
  int height_px = 0;
  int plot_left_px = 0;  // the framed plot area: data inside it, labels outside
  int plot_top_px = 0;
  int plot_width_px = 0;
  int plot_height_px = 0;
  int legend_left_px = 0;  // the legend panel, right of the plot area
  int legend_top_px = 0;
  int legend_width_px = 0;
  int legend_height_px = 0;
  double x_min = 0.0;  // the ranges the plot area spans, in data units (positive with log_y)
  double x_max = 1.0;
  double y_min = 0.0;
  double y_max = 1.0;
  bool log_y = false;
  std::vector<double> x_ticks, y_ticks;               // labelled ticks, inside the ranges
  std::vector<std::string> x_tick_labels, y_tick_labels;  // one per tick ("" where a label would overlap its neighbour)
  std::vector<double> y_minor_ticks;                  // log_y: unlabelled 2..9 x 10^k, drawn as a fainter grid
  double dodge_px = 0.0;                              // PlotSpec::dodge_px
  std::size_t series_count = 0;

  // The continuous pixel position (column, row) of the data point (x, y): pixel (i, j) covers
  // [i, i + 1) x [j, j + 1); x grows to the right, y upwards (linearly in log10 y with log_y).
  Eigen::Vector2d toPixel(double x, double y) const;
  // Where series `series` draws its point (x, y): toPixel, moved right by the series' dodge.
  Eigen::Vector2d pointPixel(std::size_t series, double x, double y) const;
};

// The layout drawLinePlot uses for `spec` in a width_px x height_px picture.
// Errors as drawLinePlot's kInvalidArgument.
Expected<PlotLayout> plotLayout(const PlotSpec& spec, int width_px = 900, int height_px = 560);

// Draws `spec` as a line chart into a PNG file at `png` (PNG whatever the extension), width_px in
// [320, 8000] and height_px in [240, 8000]. The same input gives the same bytes.
// Errors (kInvalidArgument, nothing written): no series; x, y, y_low, y_high of different lengths;
// a non-finite x or an infinite y; no finite y at all; with log_y a value or range end <= 0;
// y_min >= y_max; dodge_px out of range; a size out of range. The file cannot be written: kIo, naming it.
Status drawLinePlot(const std::filesystem::path& png, const PlotSpec& spec, int width_px = 900, int height_px = 560);

}  // namespace fogmap::pictures
