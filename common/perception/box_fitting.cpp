#include "common/perception/box_fitting.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include "common/base/angles.hpp"
#include "common/base/text.hpp"

namespace fogmap {
namespace {

// Lanes of the score's loops: independent accumulators the compiler maps onto vector registers.
constexpr std::size_t kScoreLanes = 8;

// The points' (x, y) relative to their mean, in float: the search's input.
struct Footprint {
  std::vector<float> x, y;
  double mean_x = 0.0, mean_y = 0.0;
};

// The criterion at (c, s) = (cos t, sin t), in float over lanes: pass 1 the extents, pass 2 the sum.
// Pass 2 projects with the same operations, so every distance to an extent is at least 0.
float scoreAt(const Footprint& f, float c, float s, float d0) {
  const std::size_t n = f.x.size();
  const std::size_t blocks = n / kScoreLanes * kScoreLanes;
  const float* x = f.x.data();
  const float* y = f.y.data();
  constexpr float inf = std::numeric_limits<float>::infinity();
  float min1[kScoreLanes], max1[kScoreLanes], min2[kScoreLanes], max2[kScoreLanes];
  std::fill(min1, min1 + kScoreLanes, inf);
  std::fill(min2, min2 + kScoreLanes, inf);
  std::fill(max1, max1 + kScoreLanes, -inf);
  std::fill(max2, max2 + kScoreLanes, -inf);
  for (std::size_t i = 0; i < blocks; i += kScoreLanes) {
    for (std::size_t l = 0; l < kScoreLanes; ++l) {
      const float a = c * x[i + l] + s * y[i + l];
      const float b = c * y[i + l] - s * x[i + l];
      min1[l] = a < min1[l] ? a : min1[l];
      max1[l] = a > max1[l] ? a : max1[l];
      min2[l] = b < min2[l] ? b : min2[l];
      max2[l] = b > max2[l] ? b : max2[l];
    }
  }
  float lo1 = inf, hi1 = -inf, lo2 = inf, hi2 = -inf;
  for (std::size_t l = 0; l < kScoreLanes; ++l) {
    lo1 = std::min(lo1, min1[l]);
    hi1 = std::max(hi1, max1[l]);
    lo2 = std::min(lo2, min2[l]);
    hi2 = std::max(hi2, max2[l]);
  }
  for (std::size_t i = blocks; i < n; ++i) {
    const float a = c * x[i] + s * y[i];
    const float b = c * y[i] - s * x[i];
    lo1 = std::min(lo1, a);
    hi1 = std::max(hi1, a);
    lo2 = std::min(lo2, b);
    hi2 = std::max(hi2, b);
  }
  float sum[kScoreLanes] = {};
  for (std::size_t i = 0; i < blocks; i += kScoreLanes) {
    for (std::size_t l = 0; l < kScoreLanes; ++l) {
      const float a = c * x[i + l] + s * y[i + l];
      const float b = c * y[i + l] - s * x[i + l];
      const float d1 = std::min(hi1 - a, a - lo1);
      const float d2 = std::min(hi2 - b, b - lo2);
      const float d = std::max(std::min(d1, d2), d0);
      sum[l] += 1.0F / d;
    }
  }
  float total = 0.0F;
  for (std::size_t l = 0; l < kScoreLanes; ++l) total += sum[l];
  for (std::size_t i = blocks; i < n; ++i) {
    const float a = c * x[i] + s * y[i];
    const float b = c * y[i] - s * x[i];
    const float d = std::max(std::min(std::min(hi1 - a, a - lo1), std::min(hi2 - b, b - lo2)), d0);
    total += 1.0F / d;
  }
  return total;
}

// The yaw of highest score among first + k step for k in [0, count). Where consecutive yaws tie
// (every point within d0 of an edge at each: a straight face scores alike over about
// +-asin(d0 / length)), the middle of the first tied run.
double bestYaw(const Footprint& f, double first, double step, int count, float d0) {
  int run_first = 0;
  int run_last = 0;
  float best_score = -1.0F;
  for (int k = 0; k < count; ++k) {
    const double t = first + k * step;
    const float score = scoreAt(f, static_cast<float>(std::cos(t)), static_cast<float>(std::sin(t)), d0);
    if (score > best_score) {
      best_score = score;
      run_first = run_last = k;
    } else if (score == best_score && run_last == k - 1) {
      run_last = k;
    }
  }
  return first + (run_first + (run_last - run_first) / 2) * step;
}

}  // namespace

Status validateBoxFitParams(const BoxFitParams& params) {
  if (!std::isfinite(params.coarse_step_deg) || !(params.coarse_step_deg > 0.0) || params.coarse_step_deg > 90.0) {
    return invalidArgument("box fit coarse_step_deg must be in (0, 90], got " + readableNumber(params.coarse_step_deg));
  }
  if (!std::isfinite(params.fine_step_deg) || !(params.fine_step_deg > 0.0) || params.fine_step_deg > params.coarse_step_deg) {
    return invalidArgument("box fit fine_step_deg must be positive and at most coarse_step_deg, got " + readableNumber(params.fine_step_deg));
  }
  if (!std::isfinite(params.min_distance_m) || !(params.min_distance_m > 0.0)) {
    return invalidArgument("box fit min_distance_m must be positive and finite, got " + readableNumber(params.min_distance_m));
  }
  return {};
}

double closenessScore(std::span<const Point> points, double yaw, double min_distance_m) {
  const double c = std::cos(yaw);
  const double s = std::sin(yaw);
  double lo1 = std::numeric_limits<double>::infinity(), hi1 = -lo1, lo2 = lo1, hi2 = -lo1;
  for (const Point& p : points) {
    if (!isFinitePoint(p)) continue;
    const double a = c * p.x + s * p.y;
    const double b = -s * p.x + c * p.y;
    lo1 = std::min(lo1, a);
    hi1 = std::max(hi1, a);
    lo2 = std::min(lo2, b);
    hi2 = std::max(hi2, b);
  }
  double score = 0.0;
  for (const Point& p : points) {
    if (!isFinitePoint(p)) continue;
    const double a = c * p.x + s * p.y;
    const double b = -s * p.x + c * p.y;
    const double d = std::max(std::min({hi1 - a, a - lo1, hi2 - b, b - lo2}), min_distance_m);
    score += 1.0 / d;
  }
  return score;
}

namespace {

// The finite points' footprint about their mean, and their heights.
struct Footprint3 {
  Footprint f;
  double z_lo = std::numeric_limits<double>::infinity();
  double z_hi = -std::numeric_limits<double>::infinity();
};

Expected<Footprint3> footprintOf(std::span<const Point> points) {
  Footprint3 out;
  Footprint& f = out.f;
  f.x.reserve(points.size());
  f.y.reserve(points.size());
  double sx = 0.0, sy = 0.0;
  std::size_t finite = 0;
  for (const Point& p : points) {
    if (!isFinitePoint(p)) continue;
    sx += p.x;
    sy += p.y;
    out.z_lo = std::min(out.z_lo, static_cast<double>(p.z));
    out.z_hi = std::max(out.z_hi, static_cast<double>(p.z));
    ++finite;
  }
  if (finite == 0) return invalidArgument("an oriented box needs at least one finite point, got none of " + std::to_string(points.size()));
  f.mean_x = sx / static_cast<double>(finite);
  f.mean_y = sy / static_cast<double>(finite);
  for (const Point& p : points) {
    if (!isFinitePoint(p)) continue;
    f.x.push_back(static_cast<float>(p.x - f.mean_x));
    f.y.push_back(static_cast<float>(p.y - f.mean_y));
  }
  return out;
}

// The box at yaw t, in double from the points as given.
OrientedBox boxAt(const Footprint3& footprint, double t, const std::optional<Eigen::Vector3d>& sensor) {
  const Footprint& f = footprint.f;
  const double c = std::cos(t);
  const double s = std::sin(t);
  double lo1 = std::numeric_limits<double>::infinity(), hi1 = -lo1, lo2 = lo1, hi2 = -lo1;
  for (std::size_t i = 0; i < f.x.size(); ++i) {
    const double x = f.x[i];
    const double y = f.y[i];
    const double a = c * x + s * y;
    const double b = -s * x + c * y;
    lo1 = std::min(lo1, a);
    hi1 = std::max(hi1, a);
    lo2 = std::min(lo2, b);
    hi2 = std::max(hi2, b);
  }
  const double m1 = 0.5 * (lo1 + hi1);
  const double m2 = 0.5 * (lo2 + hi2);
  OrientedBox box;
  box.centre = Eigen::Vector3d(f.mean_x + c * m1 - s * m2, f.mean_y + s * m1 + c * m2, 0.5 * (footprint.z_lo + footprint.z_hi));
  box.height = footprint.z_hi - footprint.z_lo;
  const double extent1 = hi1 - lo1;
  const double extent2 = hi2 - lo2;
  if (extent1 >= extent2) {
    box.length = extent1;
    box.width = extent2;
    box.yaw = foldedYaw(t);
  } else {
    box.length = extent2;
    box.width = extent1;
    box.yaw = foldedYaw(t + 0.5 * std::numbers::pi);
  }
  if (sensor) box.anchor = box.anchorFor(*sensor);
  return box;
}

}  // namespace

Expected<OrientedBox> orientedBoxAtYaw(std::span<const Point> points, double yaw, const std::optional<Eigen::Vector3d>& sensor) {
  if (!std::isfinite(yaw)) return invalidArgument("an oriented box's yaw must be finite, got " + std::to_string(yaw));
  const auto footprint = footprintOf(points);
  if (!footprint) return footprint.error();
  return boxAt(*footprint, yaw, sensor);
}

Expected<OrientedBox> fitOrientedBox(std::span<const Point> points, const std::optional<Eigen::Vector3d>& sensor,
                                     const BoxFitParams& params) {
  if (Status valid = validateBoxFitParams(params); !valid) return valid.error();
  const auto footprint = footprintOf(points);
  if (!footprint) return footprint.error();
  const Footprint& f = footprint->f;

  // The score repeats every 90 degrees (the same rectangle with its axes swapped): the fine search
  // around the best coarse yaw may cross 0 or 90 freely.
  const auto d0 = static_cast<float>(params.min_distance_m);
  const double coarse = params.coarse_step_deg * kDegToRad;
  const double fine = params.fine_step_deg * kDegToRad;
  const int coarse_count = static_cast<int>(std::ceil(90.0 / params.coarse_step_deg - 1e-9));
  double t = bestYaw(f, 0.0, coarse, coarse_count, d0);
  // Refinement: about a quarter of the last step, rounded up to a whole number of fine steps (every
  // yaw tried lies on the fine grid), within one last step either side.
  for (double step = coarse; step > fine * (1.0 + 1e-9);) {
    const double next = std::max(fine, std::ceil(step / 4.0 / fine - 1e-9) * fine);
    const int half = static_cast<int>(std::ceil(step / next - 1e-9));
    t = bestYaw(f, t - half * next, next, 2 * half + 1, d0);
    step = next;
  }

  return boxAt(*footprint, t, sensor);
}

OrientedBox grownToPrior(const OrientedBox& box, const Eigen::Vector3d& sensor, const BoxPrior& prior,
                         std::optional<double> heading) {
  const double c = std::cos(box.yaw);
  const double s = std::sin(box.yaw);
  // The box's axes: e1 along its length (extent a), e2 across (extent b).
  Eigen::Vector2d e1(c, s), e2(-s, c);
  double a = box.length, b = box.width;
  const bool long_edge_is_width = heading ? axisAngleBetween(box.yaw, *heading) > 0.25 * std::numbers::pi
                                          : a < prior.length_m && a <= prior.max_width_m;
  // The object's length axis and width axis, with their extents.
  Eigen::Vector2d along = e1, across = e2;
  double length = a, width = b;
  if (long_edge_is_width) {
    along = e2;
    across = e1;
    length = b;
    width = a;
  }
  Eigen::Vector2d centre = box.centre.head<2>();
  const Eigen::Vector2d to_sensor = sensor.head<2>() - centre;
  auto grow = [&](const Eigen::Vector2d& axis, double extent, double wanted) {
    if (!(extent < wanted)) return extent;
    const double u = to_sensor.dot(axis);
    const double delta = wanted - extent;
    if (std::abs(u) > 0.5 * extent) centre -= (u > 0 ? 1.0 : -1.0) * 0.5 * delta * axis;  // the near face stays
    return wanted;
  };
  length = grow(along, length, prior.length_m);
  width = grow(across, width, prior.width_m);
  OrientedBox out = box;
  out.centre.head<2>() = centre;
  out.length = std::max(length, width);
  out.width = std::min(length, width);
  const Eigen::Vector2d length_axis = length >= width ? along : across;
  out.yaw = foldedYaw(std::atan2(length_axis.y(), length_axis.x()));
  out.anchor = out.anchorFor(sensor);
  return out;
}

OrientedBox grownFromAnchor(const OrientedBox& box, const BoxPrior& prior, std::optional<double> heading) {
  Eigen::Vector3d sensor = box.centre;
  if (box.anchor != BoxAnchor::kNone) {
    const Eigen::Vector3d outward = box.anchorPoint() - box.centre;
    if (outward.head<2>().norm() > 0.0) sensor = box.anchorPoint() + 1e3 * outward.normalized();
  }
  return grownToPrior(box, sensor, prior, heading);
}

std::optional<BoxPrior> vehiclePriorFor(const OrientedBox& box, const std::optional<ObjectLabel>& label) {
  if (label) {
    if (auto prior = vehiclePrior(label->object_class)) return prior;
  }
  if (box.length >= kVehicleMinLengthM) return vehiclePrior(ObjectClass::kCar);
  return std::nullopt;
}

std::optional<BoxPrior> vehiclePrior(ObjectClass object_class) {
  if (object_class == ObjectClass::kCar) return BoxPrior{};
  if (object_class == ObjectClass::kTruckOrBus) return BoxPrior{8.0, 2.5, 3.0};
  return std::nullopt;
}

}  // namespace fogmap
