#include "pictures/birdseye.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <optional>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "common/geometry/object_shape.hpp"
#include "common/geometry/symmetric_eigen.hpp"
#include "pictures/drawing.hpp"

namespace fogmap::pictures {
namespace {

using drawing::bgr;
using drawing::fixedLength;
using drawing::fixedPoint;
using drawing::kFixed;
using drawing::kFrameColour;
using drawing::kMutedTextColour;
using drawing::kShift;
using drawing::kTextColour;
using drawing::multiplesIn;
using drawing::Pen;

constexpr double kFillAlpha = 0.18;  // objects' ellipses are tinted this much with their colour
const cv::Scalar kMapGridColour(225, 225, 225);
const cv::Scalar kOriginColour(185, 185, 185);
const cv::Scalar kRangeColour(200, 140, 140);  // BGR: a faint slate blue

// The map's transform: common-frame metres to image pixels (x right, y up), continuous coordinates
// where pixel (i, j) covers [i, i + 1) x [j, j + 1).
struct Projection {
  double left = 0.0;   // pixel column of x = x_min
  double top = 0.0;    // pixel row of y = y_max
  double x_min = 0.0;
  double y_max = 0.0;
  double px_per_m = 1.0;

  Eigen::Vector2d pixel(const Eigen::Vector2d& xy) const {
    return {left + (xy.x() - x_min) * px_per_m, top + (y_max - xy.y()) * px_per_m};
  }
};

std::vector<cv::Point> fixedPolygon(const Projection& proj, const std::vector<Eigen::Vector2d>& polygon) {
  std::vector<cv::Point> out;
  out.reserve(polygon.size());
  for (const auto& p : polygon) out.push_back(fixedPoint(proj.pixel(p)));
  return out;
}

// The x-y marginal of an ellipsoid: the ellipse {p : (p - c)^T S_xy^-1 (p - c) <= 1} (the shadow
// of the ellipsoid on the ground), as a polygon of `sides` vertices; empty when S is not usable.
std::vector<Eigen::Vector2d> marginalEllipse(const Ellipsoid& e, int sides) {
  const Eigen::Matrix2d s = e.shape.topLeftCorner<2, 2>();
  if (!s.allFinite() || !e.center.head<2>().allFinite()) return {};
  const SymmetricEigen<2> eigen = symmetricEigen(s);
  const Eigen::Vector2d axes = eigen.values.cwiseMax(0.0).cwiseSqrt();
  const Eigen::Matrix2d v = eigen.vectors;
  std::vector<Eigen::Vector2d> out;
  out.reserve(static_cast<std::size_t>(sides));
  for (int i = 0; i < sides; ++i) {
    const double a = 2.0 * M_PI * i / sides;
    out.push_back(e.center.head<2>() + v * Eigen::Vector2d(axes[0] * std::cos(a), axes[1] * std::sin(a)));
  }
  return out;
}

// The centre and a radius that holds an object's ellipses on the ground.
std::pair<Eigen::Vector2d, double> groundDisc(const MapObject& object) {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  int n = 0;
  for (const auto& e : object.ellipsoids) {
    if (!e.center.head<2>().allFinite()) continue;
    centre += e.center.head<2>();
    ++n;
  }
  if (n == 0) return {Eigen::Vector2d::Zero(), -1.0};
  centre /= n;
  double radius = 0.0;
  for (const auto& e : object.ellipsoids) {
    const Eigen::Matrix2d s = e.shape.topLeftCorner<2, 2>();
    if (!e.center.head<2>().allFinite() || !s.allFinite()) continue;
    const double reach = std::sqrt(std::max(0.0, symmetricEigen(s).values.maxCoeff()));
    radius = std::max(radius, (e.center.head<2>() - centre).norm() + reach);
  }
  return {centre, radius};
}

std::string metres(double v) {
  char text[32];
  std::snprintf(text, sizeof(text), "%g", std::abs(v) < 1e-9 ? 0.0 : v);
  return text;
}

std::string withThousands(std::size_t n) {
  const std::string digits = std::to_string(n);
  std::string out;
  for (std::size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % 3 == 0) out += ',';
    out += digits[i];
  }
  return out;
}

std::string plural(std::size_t n, const std::string& noun) { return withThousands(n) + " " + noun + (n == 1 ? "" : "s"); }

// The grid's spacing: at most 10 cells across the square, and no finer than a centimetre.
double gridSpacing(double half_extent_m) { return std::max(0.01, drawing::niceStep(2.0 * half_extent_m, 10)); }

void drawDashedCircle(cv::Mat& plot, const Projection& proj, const Eigen::Vector2d& centre, double radius_m, const cv::Scalar& colour) {
  const double radius_px = radius_m * proj.px_per_m;
  // Dashes of about 10 pixels, gaps as long.
  const int dashes = std::clamp(static_cast<int>(2.0 * M_PI * radius_px / 20.0), 12, 2048);
  for (int i = 0; i < dashes; ++i) {
    std::vector<cv::Point> dash;
    for (int k = 0; k <= 4; ++k) {
      const double a = 2.0 * M_PI * (i + 0.5 * k / 4.0) / dashes;
      dash.push_back(fixedPoint(proj.pixel(centre + radius_m * Eigen::Vector2d(std::cos(a), std::sin(a)))));
    }
    cv::polylines(plot, dash, false, colour, 1, cv::LINE_AA, kShift);
  }
}

// A sensor: a black disc with a white rim and a tick towards its heading (its x axis on the ground).
void drawSensorMarker(cv::Mat& image, const Eigen::Vector2d& px, const Eigen::Vector2d& heading_px, double radius_px) {
  const cv::Point c = fixedPoint(px);
  const int r = fixedLength(radius_px);
  if (heading_px.norm() > 0.1) {
    const Eigen::Vector2d tip = px + heading_px.normalized() * radius_px * 2.4;
    cv::line(image, c, fixedPoint(tip), cv::Scalar(255, 255, 255), 5, cv::LINE_AA, kShift);
    cv::line(image, c, fixedPoint(tip), bgr(kBirdseyeSensorColour), 2, cv::LINE_AA, kShift);
  }
  cv::circle(image, c, r + static_cast<int>(2 * kFixed), cv::Scalar(255, 255, 255), cv::FILLED, cv::LINE_AA, kShift);
  cv::circle(image, c, r, bgr(kBirdseyeSensorColour), cv::FILLED, cv::LINE_AA, kShift);
}

// A track: a diamond in its colour (hollow when lost) with a white rim, so it reads over its object.
void drawTrackMarker(cv::Mat& image, const Eigen::Vector2d& px, double radius_px, const Rgb& colour, bool confirmed) {
  std::vector<cv::Point> diamond;
  for (const Eigen::Vector2d& d : {Eigen::Vector2d(0, -1), Eigen::Vector2d(1, 0), Eigen::Vector2d(0, 1), Eigen::Vector2d(-1, 0)}) {
    diamond.push_back(fixedPoint(px + radius_px * d));
  }
  const int line = std::max(1, static_cast<int>(std::lround(radius_px / 3.5)));
  cv::polylines(image, diamond, true, cv::Scalar(255, 255, 255), line + 3, cv::LINE_AA, kShift);
  cv::fillConvexPoly(image, diamond, confirmed ? bgr(colour) : cv::Scalar(255, 255, 255), cv::LINE_AA, kShift);
  cv::polylines(image, diamond, true, bgr(colour), line, cv::LINE_AA, kShift);
}

// A track's recent positions as a line in its colour, oldest first, ending at the track.
void drawTrackTrail(cv::Mat& image, const std::vector<Eigen::Vector2d>& px, const Rgb& colour, double unit) {
  if (px.size() < 2) return;
  std::vector<cv::Point> line;
  line.reserve(px.size());
  for (const auto& p : px) line.push_back(fixedPoint(p));
  cv::polylines(image, line, false, bgr(colour), std::max(1, static_cast<int>(std::lround(2.0 * unit))), cv::LINE_AA, kShift);
}

// A missed true object: a ring with a cross through it in kBirdseyeMissedColour on a white halo,
// larger than a track's diamond so that neither hides the other.
void drawMissedMarker(cv::Mat& image, const Eigen::Vector2d& px, double radius_px, double unit) {
  const int line = std::max(2, static_cast<int>(std::lround(2.0 * unit)));
  const int halo = line + std::max(2, static_cast<int>(std::lround(2.0 * unit)));
  const double arm = radius_px / std::sqrt(2.0);
  const std::array<std::pair<Eigen::Vector2d, Eigen::Vector2d>, 2> cross = {{{{-arm, -arm}, {arm, arm}}, {{-arm, arm}, {arm, -arm}}}};
  const cv::Point c = fixedPoint(px);
  const int r = fixedLength(radius_px);
  const cv::Scalar white(255, 255, 255);
  cv::circle(image, c, r, white, halo, cv::LINE_AA, kShift);
  for (const auto& [a, b] : cross) cv::line(image, fixedPoint(px + a), fixedPoint(px + b), white, halo, cv::LINE_AA, kShift);
  cv::circle(image, c, r, bgr(kBirdseyeMissedColour), line, cv::LINE_AA, kShift);
  for (const auto& [a, b] : cross) {
    cv::line(image, fixedPoint(px + a), fixedPoint(px + b), bgr(kBirdseyeMissedColour), line, cv::LINE_AA, kShift);
  }
}

struct Counts {
  std::size_t points = 0;
  std::size_t points_in_view = 0;
  std::size_t objects_in_view = 0;
  std::size_t ellipsoids = 0;
  std::size_t tracks_in_view = 0;
  std::size_t tracks_lost = 0;
  std::size_t tracks_unlabelled = 0;  // in view, but every place for its label was taken
  std::size_t missed_in_view = 0;
  // Objects with an oriented box, by their class (the last: boxes without a class).
  std::array<std::size_t, kObjectClassCount + 1> boxes{};
};

// The map itself, into `plot` (a view of the picture clipped to the map's square).
Counts drawMap(cv::Mat& plot, const Projection& proj, const BirdseyeScene& scene, const BirdseyeLayout& layout,
               const std::vector<Rgb>& colours, double unit) {
  Counts counts;
  const double h = scene.half_extent_m;
  const Eigen::Vector2d lo = scene.center - Eigen::Vector2d::Constant(h);
  const Eigen::Vector2d hi = scene.center + Eigen::Vector2d::Constant(h);
  // `proj` is relative to the whole picture; `plot` is its view that starts at (left, top).
  Projection local = proj;
  local.left = 0.0;
  local.top = 0.0;
  // Sensor ranges under everything.
  for (const auto& s : scene.sensors) {
    if (s.range_m > 0.0 && std::isfinite(s.range_m) && s.pose.translation().allFinite()) {
      drawDashedCircle(plot, local, s.pose.translation().head<2>(), s.range_m, kRangeColour);
    }
  }
  // Grid, then the axes through the origin a little darker.
  const double step = layout.grid_m;
  for (const double v : multiplesIn(lo.x(), hi.x(), step)) {
    const bool origin = std::abs(v) < step * 1e-6;
    cv::line(plot, fixedPoint(local.pixel({v, lo.y()})), fixedPoint(local.pixel({v, hi.y()})), origin ? kOriginColour : kMapGridColour, 1,
             cv::LINE_AA, kShift);
  }
  for (const double v : multiplesIn(lo.y(), hi.y(), step)) {
    const bool origin = std::abs(v) < step * 1e-6;
    cv::line(plot, fixedPoint(local.pixel({lo.x(), v})), fixedPoint(local.pixel({hi.x(), v})), origin ? kOriginColour : kMapGridColour, 1,
             cv::LINE_AA, kShift);
  }
  std::vector<std::vector<std::vector<cv::Point>>> ellipses(scene.objects.size());
  for (std::size_t o = 0; o < scene.objects.size(); ++o) {
    bool in_view = false;
    for (const auto& e : scene.objects[o].ellipsoids) {
      ++counts.ellipsoids;
      const auto polygon = marginalEllipse(e, 72);
      if (polygon.empty()) continue;
      in_view = in_view || ((e.center.head<2>().array() >= lo.array()).all() && (e.center.head<2>().array() <= hi.array()).all());
      ellipses[o].push_back(fixedPolygon(local, polygon));
    }
    if (in_view) ++counts.objects_in_view;
  }
  // Objects' insides tinted with their colour, then points, true outlines, and the ellipses' outlines on top.
  cv::Mat tint = plot.clone();
  for (std::size_t o = 0; o < ellipses.size(); ++o) {
    if (!ellipses[o].empty()) cv::fillPoly(tint, ellipses[o], bgr(colours[o]), cv::LINE_AA, kShift);
  }
  cv::addWeighted(tint, kFillAlpha, plot, 1.0 - kFillAlpha, 0.0, plot);
  // Points: one pixel each, over the tint so they show inside objects too.
  const cv::Vec3b point_colour(kBirdseyePointColour.b, kBirdseyePointColour.g, kBirdseyePointColour.r);
  for (const auto& cloud : scene.points) {
    for (const Point& p : cloud) {
      if (!isFinitePoint(p)) continue;
      ++counts.points;
      const Eigen::Vector2d px = local.pixel({p.x, p.y});
      const double col = std::floor(px.x());
      const double row = std::floor(px.y());
      if (col < 0 || row < 0 || col >= plot.cols || row >= plot.rows) continue;
      ++counts.points_in_view;
      plot.at<cv::Vec3b>(static_cast<int>(row), static_cast<int>(col)) = point_colour;
    }
  }
  for (const auto& outline : scene.truth) {
    if (outline.polygon.size() < 2) continue;
    cv::polylines(plot, fixedPolygon(local, outline.polygon), true, bgr(kBirdseyeTruthColour), 1, cv::LINE_AA, kShift);
  }
  const int outline_px = std::max(1, static_cast<int>(std::lround(2.0 * unit)));
  for (std::size_t o = 0; o < ellipses.size(); ++o) {
    if (!ellipses[o].empty()) cv::polylines(plot, ellipses[o], true, bgr(colours[o]), outline_px, cv::LINE_AA, kShift);
  }
  // Oriented boxes over the ellipses, in their class's colour.
  for (const MapObject& object : scene.objects) {
    const auto box = objectBox(object);
    if (!box || !box->centre.allFinite()) continue;
    const auto label = objectLabel(object);
    ++counts.boxes[label ? static_cast<std::size_t>(label->object_class) : kObjectClassCount];
    const auto corners = box->footprint();
    const std::vector<Eigen::Vector2d> polygon(corners.begin(), corners.end());
    cv::polylines(plot, fixedPolygon(local, polygon), true, bgr(birdseyeClassColour(label ? std::optional(label->object_class) : std::nullopt)),
                  outline_px, cv::LINE_AA, kShift);
  }
  // Missed true objects over the objects and the truth, under the tracks.
  if (scene.missed) {
    for (const auto& centre : *scene.missed) {
      if (!centre.allFinite()) continue;
      const Eigen::Vector2d at = local.pixel(centre);
      if (at.x() < 0 || at.y() < 0 || at.x() >= plot.cols || at.y() >= plot.rows) continue;
      ++counts.missed_in_view;
      drawMissedMarker(plot, at, 10.0 * unit, unit);
    }
  }
  // Tracks over the map: trails, then markers, then their ids and labels.
  const double marker = 7.0 * unit;
  for (const auto& track : scene.tracks) {
    std::vector<Eigen::Vector2d> trail;
    for (const auto& p : track.trail) {
      if (p.allFinite()) trail.push_back(local.pixel(p));
    }
    if (!track.position.allFinite()) continue;
    trail.push_back(local.pixel(track.position));
    drawTrackTrail(plot, trail, birdseyeTrackColour(track.id), unit);
  }
  const Pen track_pen{0.45 * unit, 1};
  for (const auto& track : scene.tracks) {
    if (!track.position.allFinite()) continue;
    if (!track.confirmed) ++counts.tracks_lost;
    const Eigen::Vector2d at = local.pixel(track.position);
    if (at.x() < 0 || at.y() < 0 || at.x() >= plot.cols || at.y() >= plot.rows) continue;
    ++counts.tracks_in_view;
    if (track.heading_rad && std::isfinite(*track.heading_rad)) {
      // The heading as a tick of 2.5 marker radii from the centre, under the marker, white-edged
      // (its label keeps off that side).
      const Eigen::Vector2d ahead =
          local.pixel(track.position + Eigen::Vector2d(std::cos(*track.heading_rad), std::sin(*track.heading_rad))) - at;
      if (ahead.norm() > 0.0) {
        const Eigen::Vector2d tip = at + ahead.normalized() * 2.5 * marker;
        const int line = std::max(1, static_cast<int>(std::lround(marker / 3.5)));
        cv::line(plot, fixedPoint(at), fixedPoint(tip), cv::Scalar(255, 255, 255), line + 3, cv::LINE_AA, kShift);
        cv::line(plot, fixedPoint(at), fixedPoint(tip), bgr(birdseyeTrackColour(track.id)), line, cv::LINE_AA, kShift);
      }
    }
    drawTrackMarker(plot, at, marker, birdseyeTrackColour(track.id), track.confirmed);
  }
  // Their ids and labels, confirmed tracks first: each on the first free side of its marker, ahead
  // of it (away from its trail) where that is free, and left out where every side would cover
  // another label (many lost tracks in one place).
  std::vector<const BirdseyeTrack*> labelled;
  for (const auto& track : scene.tracks) {
    if (track.confirmed) labelled.push_back(&track);
  }
  for (const auto& track : scene.tracks) {
    if (!track.confirmed) labelled.push_back(&track);
  }
  std::vector<cv::Rect> taken;
  for (const BirdseyeTrack* track : labelled) {
    if (!track->position.allFinite()) continue;
    const Eigen::Vector2d at = local.pixel(track->position);
    if (at.x() < 0 || at.y() < 0 || at.x() >= plot.cols || at.y() >= plot.rows) continue;
    std::string text = "#";  // appended piece by piece: GCC 12 warns (-Wrestrict) about "#" + std::string
    text += std::to_string(track->id);
    text += ' ';
    text += track->label;
    const cv::Size size = track_pen.size(text);
    Eigen::Vector2d ahead(1, 0);
    if (!track->trail.empty() && track->trail.back().allFinite()) {
      const Eigen::Vector2d step = at - local.pixel(track->trail.back());
      if (step.norm() > 0.5) ahead = step.normalized();
    }
    // A vehicle's heading tick takes the side it points to: the label goes beside it instead.
    std::optional<Eigen::Vector2d> front;
    if (track->heading_rad && std::isfinite(*track->heading_rad)) {
      const Eigen::Vector2d step =
          local.pixel(track->position + Eigen::Vector2d(std::cos(*track->heading_rad), std::sin(*track->heading_rad))) - at;
      if (step.norm() > 0.0) front = step.normalized();
    }
    const double gap = marker + 3.0 * unit;
    std::vector<std::pair<double, cv::Point>> sides;  // (preference, baseline start)
    for (const auto& [direction, corner] : std::array<std::pair<Eigen::Vector2d, cv::Point2d>, 4>{{
             {{1, 0}, {at.x() + gap, at.y() + size.height / 2.0}},
             {{-1, 0}, {at.x() - gap - size.width, at.y() + size.height / 2.0}},
             {{0, 1}, {at.x() - size.width / 2.0, at.y() + gap + size.height}},
             {{0, -1}, {at.x() - size.width / 2.0, at.y() - gap}},
         }}) {
      const bool fits = corner.x >= 2 && corner.x + size.width <= plot.cols - 2 && corner.y - size.height >= 2 && corner.y <= plot.rows - 2;
      const double covers_tick = front ? 2.0 * std::max(0.0, direction.dot(*front)) : 0.0;
      sides.emplace_back(direction.dot(ahead) - covers_tick + (fits ? 10.0 : 0.0),
                         cv::Point(static_cast<int>(std::lround(corner.x)), static_cast<int>(std::lround(corner.y))));
    }
    std::stable_sort(sides.begin(), sides.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
    const int pad = static_cast<int>(std::lround(2.0 * unit));
    bool placed = false;
    for (const auto& [preference, corner] : sides) {
      const cv::Rect box(corner.x - pad, corner.y - size.height - pad, size.width + 2 * pad,
                         size.height + track_pen.descent() + 2 * pad);
      if (std::any_of(taken.begin(), taken.end(), [&](const cv::Rect& t) { return (t & box).area() > 0; })) continue;
      taken.push_back(box);
      track_pen.writeOnMap(plot, text, corner, bgr(birdseyeTrackColour(track->id)));
      placed = true;
      break;
    }
    if (!placed) ++counts.tracks_unlabelled;
  }
  // Sensors and their names last, over the data.
  const Pen label{0.5 * unit, 1};
  for (const auto& s : scene.sensors) {
    if (!s.pose.translation().allFinite()) continue;
    const Eigen::Vector2d at = local.pixel(s.pose.translation().head<2>());
    const Eigen::Vector3d x_axis = s.pose.linear().col(0);
    const Eigen::Vector2d heading = local.pixel(s.pose.translation().head<2>() + x_axis.head<2>()) - at;
    const double radius = 5.0 * unit;
    drawSensorMarker(plot, at, heading, radius);
    if (s.name.empty()) continue;
    const cv::Size size = label.size(s.name);
    // Beside the marker on the side away from its heading tick (right, left, below, above), inside the map.
    const double gap = radius + 6.0 * unit;
    const std::array<std::pair<Eigen::Vector2d, cv::Point2d>, 4> sides = {{
        {{1, 0}, {at.x() + gap, at.y() + size.height / 2.0}},
        {{-1, 0}, {at.x() - gap - size.width, at.y() + size.height / 2.0}},
        {{0, 1}, {at.x() - size.width / 2.0, at.y() + gap + size.height}},
        {{0, -1}, {at.x() - size.width / 2.0, at.y() - gap}},
    }};
    const Eigen::Vector2d away = heading.norm() > 0.1 ? Eigen::Vector2d(-heading.normalized()) : Eigen::Vector2d(1, 0);
    cv::Point2d best = sides[0].second;
    double best_score = -1e9;
    for (const auto& [direction, corner] : sides) {
      const bool fits = corner.x >= 2 && corner.x + size.width <= plot.cols - 2 && corner.y - size.height >= 2 && corner.y <= plot.rows - 2;
      const double score = direction.dot(away) + (fits ? 10.0 : 0.0);
      if (score > best_score + 1e-9) {
        best_score = score;
        best = corner;
      }
    }
    const int x = static_cast<int>(std::lround(best.x));
    const int y = static_cast<int>(std::lround(best.y));
    label.writeOnMap(plot, s.name, {x, y}, kTextColour);
  }
  cv::rectangle(plot, cv::Point(0, 0), cv::Point(plot.cols - 1, plot.rows - 1), kFrameColour, 1);
  return counts;
}

// The grid's labels in metres on the map's left and bottom edges, and the axes' names.
void drawAxes(cv::Mat& image, const Projection& proj, const BirdseyeScene& scene, const BirdseyeLayout& layout, double unit) {
  const Pen pen{0.45 * unit, 1};
  const double h = scene.half_extent_m;
  const Eigen::Vector2d lo = scene.center - Eigen::Vector2d::Constant(h);
  const Eigen::Vector2d hi = scene.center + Eigen::Vector2d::Constant(h);
  const double step = layout.grid_m;
  const int tick = static_cast<int>(std::lround(5.0 * unit));
  const int bottom = layout.plot_top_px + layout.plot_size_px;
  for (const double v : multiplesIn(lo.x(), hi.x(), step)) {
    const int col = static_cast<int>(std::lround(proj.pixel({v, 0.0}).x() - 0.5));
    cv::line(image, {col, bottom}, {col, bottom + tick}, kFrameColour, 1);
    const std::string text = metres(v);
    const cv::Size size = pen.size(text);
    pen.write(image, text, {col - size.width / 2, bottom + tick + size.height + static_cast<int>(4 * unit)}, kTextColour);
  }
  for (const double v : multiplesIn(lo.y(), hi.y(), step)) {
    const int row = static_cast<int>(std::lround(proj.pixel({0.0, v}).y() - 0.5));
    cv::line(image, {layout.plot_left_px - tick, row}, {layout.plot_left_px, row}, kFrameColour, 1);
    const std::string text = metres(v);
    const cv::Size size = pen.size(text);
    pen.write(image, text, {layout.plot_left_px - tick - static_cast<int>(4 * unit) - size.width, row + size.height / 2}, kTextColour);
  }
  const Pen name{0.5 * unit, 1};
  const std::string x_name = "x [m]";
  const cv::Size xs = name.size(x_name);
  name.write(image, x_name, {layout.plot_left_px + layout.plot_size_px / 2 - xs.width / 2, layout.height_px - static_cast<int>(10 * unit)},
             kTextColour);
  const std::string y_name = "y [m]";
  const cv::Size ys = name.size(y_name);
  name.write(image, y_name, {std::max(2, layout.plot_left_px - ys.width - static_cast<int>(6 * unit)), layout.plot_top_px - static_cast<int>(14 * unit)},
             kTextColour);
}

// The legend panel: what each mark means, counts, the axes' orientation and a scale bar.
void drawLegend(cv::Mat& image, const BirdseyeScene& scene, const BirdseyeLayout& layout, const Counts& counts, double unit) {
  const cv::Rect panel(layout.legend_left_px, layout.legend_top_px, layout.legend_width_px, layout.legend_height_px);
  cv::rectangle(image, panel, cv::Scalar(250, 250, 250), cv::FILLED);
  cv::rectangle(image, panel, kFrameColour, 1);
  const Pen heading{0.6 * unit, 2};
  const Pen body{0.45 * unit, 1};
  const int pad = static_cast<int>(std::lround(14 * unit));
  const int swatch_w = static_cast<int>(std::lround(44 * unit));
  const int text_left = panel.x + pad + swatch_w + static_cast<int>(std::lround(12 * unit));
  const int text_width = panel.x + panel.width - pad - text_left;
  const int line_h = static_cast<int>(std::lround(body.size("Ag").height * 1.9));
  int y = panel.y + pad + heading.size("Legend").height;
  heading.write(image, "Legend", {panel.x + pad, y}, kTextColour);
  y += static_cast<int>(std::lround(16 * unit));

  // One entry: a swatch drawn by `swatch` in the box (x, top, w, h), then its wrapped text.
  const auto entry = [&](const std::string& text, const std::string& detail, const auto& swatch) {
    const auto lines = body.wrap(text, text_width);
    const auto details = body.wrap(detail, text_width);
    const int rows = static_cast<int>(lines.size() + details.size());
    const int box_h = std::max(line_h * rows, static_cast<int>(std::lround(30 * unit)));
    swatch(cv::Rect(panel.x + pad, y, swatch_w, std::max(line_h * 1, static_cast<int>(std::lround(30 * unit)))));
    int ty = y + (box_h - line_h * rows) / 2 + line_h - static_cast<int>(std::lround(6 * unit));
    for (const auto& l : lines) {
      body.write(image, l, {text_left, ty}, kTextColour);
      ty += line_h;
    }
    for (const auto& l : details) {
      body.write(image, l, {text_left, ty}, kMutedTextColour);
      ty += line_h;
    }
    y += box_h + static_cast<int>(std::lround(12 * unit));
  };
  const auto centreOf = [](const cv::Rect& r) { return Eigen::Vector2d(r.x + r.width / 2.0, r.y + r.height / 2.0); };

  entry("LiDAR points", withThousands(counts.points_in_view) + " in view" +
                            (counts.points > counts.points_in_view ? " of " + withThousands(counts.points) : std::string()),
        [&](const cv::Rect& r) {
          // A small deterministic scatter.
          std::uint32_t state = 12345;
          const auto next = [&state](int n) {
            state = state * 1664525U + 1013904223U;  // a fixed linear congruential sequence
            return static_cast<int>((state >> 8) % static_cast<std::uint32_t>(n));
          };
          for (int i = 0; i < 40; ++i) {
            const int px = r.x + 3 + next(r.width - 7);
            const int py = r.y + 3 + next(r.height - 6);
            image.at<cv::Vec3b>(py, px) = cv::Vec3b(kBirdseyePointColour.b, kBirdseyePointColour.g, kBirdseyePointColour.r);
            image.at<cv::Vec3b>(py, px + 1) = cv::Vec3b(kBirdseyePointColour.b, kBirdseyePointColour.g, kBirdseyePointColour.r);
          }
        });
  std::string objects_detail = plural(scene.objects.size(), "object") + ", " + plural(counts.ellipsoids, "ellipsoid");
  if (counts.objects_in_view < scene.objects.size()) {
    objects_detail += "; " + std::to_string(scene.objects.size() - counts.objects_in_view) + " out of view";
  }
  entry("global objects: each ellipsoid's ground outline, one colour per object", objects_detail, [&](const cv::Rect& r) {
    const Eigen::Vector2d c = centreOf(r);
    for (int i = 0; i < 3; ++i) {
      const cv::Point centre = fixedPoint(c + Eigen::Vector2d((i - 1) * r.width / 3.2, (i % 2 == 0 ? -1 : 1) * r.height / 8.0));
      const cv::Size axes(static_cast<int>(r.width / 5.0 * kFixed), static_cast<int>(r.height / 3.2 * kFixed));
      cv::ellipse(image, centre, axes, 20.0 * (i - 1), 0, 360, bgr(kBirdseyePalette[i]), std::max(1, static_cast<int>(std::lround(2 * unit))),
                  cv::LINE_AA, kShift);
    }
  });
  std::size_t boxes = 0;
  std::string boxes_detail;
  for (std::size_t k = 0; k <= kObjectClassCount; ++k) {
    if (counts.boxes[k] == 0) continue;
    boxes += counts.boxes[k];
    boxes_detail += (boxes_detail.empty() ? "" : ", ") +
                    (k < kObjectClassCount ? std::string(objectClassName(static_cast<ObjectClass>(k))) : std::string("no class")) +
                    " " + withThousands(counts.boxes[k]);
  }
  if (boxes > 0) {
    entry("oriented box of an object, in its LiDAR class's colour", boxes_detail, [&](const cv::Rect& r) {
      const Eigen::Vector2d c = centreOf(r);
      const std::array<std::optional<ObjectClass>, 3> shown = {ObjectClass::kCar, ObjectClass::kPerson, ObjectClass::kTruckOrBus};
      for (int i = 0; i < 3; ++i) {
        OrientedBox b;
        b.centre = Eigen::Vector3d(c.x() + (i - 1) * r.width / 3.2, c.y(), 0.0);
        b.length = r.height * 0.8;
        b.width = r.width / 5.0;
        b.yaw = 0.5 * (i - 1) + 1.2;
        std::vector<cv::Point> poly;
        for (const Eigen::Vector2d& corner : b.footprint()) poly.push_back(fixedPoint(corner));
        cv::polylines(image, poly, true, bgr(birdseyeClassColour(shown[static_cast<std::size_t>(i)])),
                      std::max(1, static_cast<int>(std::lround(2 * unit))), cv::LINE_AA, kShift);
      }
    });
  }
  if (!scene.truth.empty()) {
    entry("true object outlines", plural(scene.truth.size(), "object") + " (simulated truth)", [&](const cv::Rect& r) {
      const Eigen::Vector2d c = centreOf(r);
      const std::vector<cv::Point> poly = {fixedPoint(c + Eigen::Vector2d(-r.width * 0.4, -r.height * 0.25)),
                                           fixedPoint(c + Eigen::Vector2d(r.width * 0.25, -r.height * 0.4)),
                                           fixedPoint(c + Eigen::Vector2d(r.width * 0.4, r.height * 0.25)),
                                           fixedPoint(c + Eigen::Vector2d(-r.width * 0.25, r.height * 0.4))};
      cv::polylines(image, poly, true, bgr(kBirdseyeTruthColour), 1, cv::LINE_AA, kShift);
    });
  }
  if (scene.missed) {
    const std::size_t missed = scene.missed->size();
    std::string detail = missed == 0 ? std::string("none: every true object found") : plural(missed, "true object");
    if (counts.missed_in_view < missed) detail += "; " + withThousands(missed - counts.missed_in_view) + " out of view";
    entry("missed: a true object no cluster found, at its centre", detail, [&](const cv::Rect& r) {
      drawMissedMarker(image, centreOf(r), std::min(r.height * 0.35, 10.0 * unit), unit);
    });
  }
  if (!scene.tracks.empty()) {
    std::string detail = plural(scene.tracks.size(), "track");
    if (counts.tracks_lost > 0) detail += ", " + withThousands(counts.tracks_lost) + " lost (hollow)";
    if (counts.tracks_in_view < scene.tracks.size()) {
      detail += "; " + withThousands(scene.tracks.size() - counts.tracks_in_view) + " out of view";
    }
    if (counts.tracks_unlabelled > 0) {
      detail += "; " + withThousands(counts.tracks_unlabelled) + " not labelled (no room)";
    }
    entry("track: #id and label at its position, a line through its recent positions", detail, [&](const cv::Rect& r) {
      const Rgb colour = kBirdseyeTrackPalette[0];
      const std::vector<Eigen::Vector2d> trail = {{r.x + 3.0, r.y + r.height * 0.85}, {r.x + r.width * 0.3, r.y + r.height * 0.6},
                                                  {r.x + r.width * 0.55, r.y + r.height * 0.45},
                                                  {r.x + r.width * 0.75, r.y + r.height * 0.35}};
      drawTrackTrail(image, trail, colour, unit);
      drawTrackMarker(image, trail.back(), 7.0 * unit, colour, true);
    });
  }
  if (!scene.sensors.empty()) {
    entry("sensor: position, name, heading (its x axis)", plural(scene.sensors.size(), "sensor"), [&](const cv::Rect& r) {
      drawSensorMarker(image, centreOf(r) - Eigen::Vector2d(r.width * 0.15, 0), Eigen::Vector2d(1, 0), 5.0 * unit);
    });
    double range_min = 0.0;
    double range_max = 0.0;
    bool any = false;
    bool visible = false;  // some circle crosses the square shown
    const Eigen::Vector2d lo = scene.center - Eigen::Vector2d::Constant(scene.half_extent_m);
    const Eigen::Vector2d hi = scene.center + Eigen::Vector2d::Constant(scene.half_extent_m);
    for (const auto& s : scene.sensors) {
      if (!(s.range_m > 0.0) || !std::isfinite(s.range_m) || !s.pose.translation().allFinite()) continue;
      range_min = any ? std::min(range_min, s.range_m) : s.range_m;
      range_max = any ? std::max(range_max, s.range_m) : s.range_m;
      any = true;
      const Eigen::Vector2d c = s.pose.translation().head<2>();
      const double nearest = (c - c.cwiseMax(lo).cwiseMin(hi)).norm();
      const double farthest = (c - lo).cwiseAbs().cwiseMax((c - hi).cwiseAbs()).norm();
      visible = visible || (nearest <= s.range_m && s.range_m <= farthest);
    }
    if (any) {
      const std::string ranges = range_min == range_max ? metres(range_min) + " m" : metres(range_min) + " to " + metres(range_max) + " m";
      entry("sensor range (360 degrees)", ranges + (visible ? "" : ", beyond the view"),
            [&](const cv::Rect& r) {
              // A projection of one pixel per unit with the swatch's corner at the origin, y down.
              const Projection swatch{static_cast<double>(r.x), static_cast<double>(r.y), 0.0, 0.0, 1.0};
              drawDashedCircle(image, swatch, Eigen::Vector2d(r.width * 0.5, -r.height * 0.5), r.height * 0.45, kRangeColour);
            });
    }
  }
  // Orientation: two arrows, x right and y up; then the scale bar.
  y += static_cast<int>(std::lround(6 * unit));
  cv::line(image, {panel.x + pad, y}, {panel.x + panel.width - pad, y}, cv::Scalar(215, 215, 215), 1);
  y += static_cast<int>(std::lround(22 * unit));
  const int arrow = static_cast<int>(std::lround(30 * unit));
  const cv::Point origin(panel.x + pad + static_cast<int>(std::lround(8 * unit)), y + arrow);
  cv::arrowedLine(image, origin, origin + cv::Point(arrow, 0), kTextColour, 1, cv::LINE_AA, 0, 0.25);
  cv::arrowedLine(image, origin, origin - cv::Point(0, arrow), kTextColour, 1, cv::LINE_AA, 0, 0.25);
  const Pen small{0.4 * unit, 1};
  small.write(image, "x", origin + cv::Point(arrow + static_cast<int>(4 * unit), static_cast<int>(4 * unit)), kTextColour);
  small.write(image, "y", origin + cv::Point(-static_cast<int>(4 * unit), -arrow - static_cast<int>(6 * unit)), kTextColour);
  int ty = y + static_cast<int>(std::lround(8 * unit));
  for (const auto& l : body.wrap("common frame, x right, y up; metres", text_width)) {
    body.write(image, l, {text_left, ty}, kTextColour);
    ty += line_h;
  }
  for (const auto& l : body.wrap("grid every " + metres(layout.grid_m) + " m", text_width)) {
    body.write(image, l, {text_left, ty}, kMutedTextColour);
    ty += line_h;
  }
  y = std::max(origin.y, ty) + static_cast<int>(std::lround(24 * unit));
  // The scale bar, at the map's scale: one grid spacing long.
  const double bar_px = layout.grid_m * layout.plot_size_px / (2.0 * scene.half_extent_m);
  const int bar_left = panel.x + pad;
  const int bar_right = bar_left + static_cast<int>(std::lround(bar_px));
  const int bar_h = static_cast<int>(std::lround(6 * unit));
  cv::rectangle(image, cv::Point(bar_left, y), cv::Point(bar_right, y + bar_h), kTextColour, cv::FILLED);
  cv::rectangle(image, cv::Point(bar_left + (bar_right - bar_left) / 2, y + 1), cv::Point(bar_right - 1, y + bar_h - 1), cv::Scalar(255, 255, 255),
                cv::FILLED);
  const std::string bar_text = metres(layout.grid_m) + " m";
  body.write(image, bar_text, {bar_right + static_cast<int>(std::lround(10 * unit)), y + bar_h}, kTextColour);
}

}  // namespace

BirdseyeLayout birdseyeLayout(const BirdseyeScene& scene, int size_px) {
  const double unit = std::max(0.5, size_px / 1000.0);  // text and margins grow with the picture
  const auto px = [&](double v) { return static_cast<int>(std::lround(v * unit)); };
  BirdseyeLayout l;
  l.plot_size_px = size_px;
  l.plot_left_px = px(70);
  l.plot_top_px = px(84);
  l.legend_left_px = l.plot_left_px + size_px + px(24);
  l.legend_top_px = l.plot_top_px;
  l.legend_width_px = px(330);
  l.legend_height_px = size_px;
  l.width_px = l.legend_left_px + l.legend_width_px + px(16);
  l.height_px = l.plot_top_px + size_px + px(62);
  l.grid_m = std::isfinite(scene.half_extent_m) && scene.half_extent_m > 0.0 ? gridSpacing(scene.half_extent_m) : 1.0;
  return l;
}

Rgb birdseyeClassColour(std::optional<ObjectClass> object_class) {
  if (!object_class || static_cast<std::size_t>(*object_class) >= kObjectClassCount) return kBirdseyeUnclassifiedColour;
  return kBirdseyeClassPalette[static_cast<std::size_t>(*object_class)];
}

std::vector<Rgb> birdseyeObjectColours(std::span<const MapObject> objects) {
  constexpr std::size_t kColours = std::size(kBirdseyePalette);
  constexpr double kClearance_m = 3.0;  // objects nearer than this (edge to edge) are neighbours
  std::vector<std::pair<Eigen::Vector2d, double>> discs;
  discs.reserve(objects.size());
  for (const auto& o : objects) discs.push_back(groundDisc(o));
  std::vector<std::size_t> chosen(objects.size());
  std::vector<Rgb> out(objects.size());
  for (std::size_t o = 0; o < objects.size(); ++o) {
    std::vector<bool> taken(kColours, false);
    if (discs[o].second >= 0.0) {
      for (std::size_t p = 0; p < o; ++p) {
        if (discs[p].second < 0.0) continue;
        if ((discs[o].first - discs[p].first).norm() < discs[o].second + discs[p].second + kClearance_m) taken[chosen[p]] = true;
      }
    }
    chosen[o] = o % kColours;  // the palette in turn, unless a neighbour has that colour
    for (std::size_t k = 0; k < kColours; ++k) {
      const std::size_t c = (o + k) % kColours;
      if (!taken[c]) {
        chosen[o] = c;
        break;
      }
    }
    out[o] = kBirdseyePalette[chosen[o]];
  }
  return out;
}

Rgb birdseyeTrackColour(std::uint64_t id) {
  return kBirdseyeTrackPalette[id % std::size(kBirdseyeTrackPalette)];
}

Status drawBirdseye(const std::filesystem::path& png, const BirdseyeScene& scene, int size_px) {
  if (!std::isfinite(scene.half_extent_m) || !(scene.half_extent_m > 0.0)) {
    return invalidArgument("birdseye: half_extent_m must be a positive number of metres");
  }
  if (!scene.center.allFinite()) return invalidArgument("birdseye: the center must be finite");
  if (size_px < 200 || size_px > 8000) return invalidArgument("birdseye: size_px must be in [200, 8000], not " + std::to_string(size_px));
  const BirdseyeLayout layout = birdseyeLayout(scene, size_px);
  const double unit = std::max(0.5, size_px / 1000.0);
  cv::Mat image(layout.height_px, layout.width_px, CV_8UC3, bgr(kBirdseyeBackground));
  Projection proj;
  proj.left = layout.plot_left_px;
  proj.top = layout.plot_top_px;
  proj.x_min = scene.center.x() - scene.half_extent_m;
  proj.y_max = scene.center.y() + scene.half_extent_m;
  proj.px_per_m = size_px / (2.0 * scene.half_extent_m);
  const std::vector<Rgb> colours = birdseyeObjectColours(scene.objects);

  cv::Mat plot = image(cv::Rect(layout.plot_left_px, layout.plot_top_px, size_px, size_px));
  const Counts counts = drawMap(plot, proj, scene, layout, colours, unit);
  drawAxes(image, proj, scene, layout, unit);
  drawLegend(image, scene, layout, counts, unit);
  // The title, shrunk until it fits the band.
  const std::string title = scene.title.empty() ? std::string("bird's-eye view") : scene.title;
  const int room = layout.width_px - 2 * layout.plot_left_px / 2;
  const Pen pen = Pen{0.75 * unit, 2}.shrunkToFit(title, room, 0.3 * unit);
  pen.write(image, title, {layout.plot_left_px / 2, static_cast<int>(std::lround(40 * unit))}, kTextColour);

  return drawing::writePng(png, image, "birdseye");
}

}  // namespace fogmap::pictures
