#include "common/sim/camera_truth.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/base/angles.hpp"
#include "common/sim/counter_random.hpp"

namespace fogmap::sim {
namespace {

// Points around a cylinder's rim: the box of a 32-gon falls short of the true silhouette by at
// most r (1 - cos(pi / 32)), half a percent of the radius.
constexpr int kRimPoints = 32;
// Nearer than this to the camera's plane a point has no usable pixel (PinholeCamera::project).
constexpr double kNearM = 0.1;

// In [0, 1) from the top 53 bits.
double unit(std::uint64_t bits) { return static_cast<double>(bits >> 11) * 0x1.0p-53; }

// The draws of one (seed, camera, frame, object): draw 0 decides the miss, draws 1 to 8 feed the
// four edges' Gaussians, so the jitter of a detection is the same whatever the miss rate.
class Draws {
 public:
  Draws(std::uint64_t seed, const std::string& camera, std::uint64_t frame, std::uint32_t object)
      : stream_(mix(mix(mix(mix(seed ^ 0x7A3C51D2E9B40F61ULL) ^ nameHash(camera)) ^ frame) ^ object)) {}
  double uniform(std::uint64_t index) const { return unit(mix(stream_ + index)); }
  // Box-Muller on draws 2k+1 and 2k+2; 1 - u keeps the logarithm's argument in (0, 1].
  double gaussian(std::uint64_t k) const {
    const double u1 = 1.0 - uniform(2 * k + 1);
    const double u2 = uniform(2 * k + 2);
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
  }

 private:
  std::uint64_t stream_;
};

// Where a part stands at the instant: its footprint centre, the heading of its x axis, its bottom
// and top heights (the raycaster's placement: objects stand on the ground where their origin is).
struct PlacedPart {
  Eigen::Vector2d centre;
  double yaw_rad;
  double z0, z1;
  const Part* part;
};

std::vector<PlacedPart> placeParts(const Scene& scene, const SceneObject& object, double time_s) {
  const ObjectPose pose = poseAt(object, time_s);
  const Eigen::Rotation2Dd heading(pose.yaw_rad);
  const double ground_z = scene.ground.heightAt(pose.xy.x());
  std::vector<PlacedPart> placed;
  for (const Part& part : object.parts) {
    const double z0 = ground_z + part.at.z();
    placed.push_back({pose.xy + heading * part.at.head<2>(), pose.yaw_rad + part.yaw_deg * kDegToRad, z0,
                      z0 + part.size.z(), &part});
  }
  return placed;
}

// The points whose projections bound the part's image.
std::vector<Eigen::Vector3d> outline(const PlacedPart& p) {
  std::vector<Eigen::Vector3d> points;
  if (p.part->shape == Shape::kCylinder) {
    const double r = p.part->size.x() / 2.0;
    for (int i = 0; i < kRimPoints; ++i) {
      const double a = 2.0 * M_PI * i / kRimPoints;
      const Eigen::Vector2d xy = p.centre + r * Eigen::Vector2d(std::cos(a), std::sin(a));
      points.emplace_back(xy.x(), xy.y(), p.z0);
      points.emplace_back(xy.x(), xy.y(), p.z1);
    }
    return points;
  }
  const Eigen::Rotation2Dd yaw(p.yaw_rad);
  const Eigen::Vector2d ax = yaw * Eigen::Vector2d(p.part->size.x() / 2.0, 0.0);
  const Eigen::Vector2d ay = yaw * Eigen::Vector2d(0.0, p.part->size.y() / 2.0);
  for (const double sx : {-1.0, 1.0}) {
    for (const double sy : {-1.0, 1.0}) {
      const Eigen::Vector2d xy = p.centre + sx * ax + sy * ay;
      points.emplace_back(xy.x(), xy.y(), p.z0);
      points.emplace_back(xy.x(), xy.y(), p.z1);
    }
  }
  return points;
}

// The points a visibility ray aims at: the part's centre and the centres of its faces (for a
// cylinder, its top and bottom and four points around its side).
std::vector<Eigen::Vector3d> samples(const PlacedPart& p) {
  const double mid = (p.z0 + p.z1) / 2.0;
  const Eigen::Rotation2Dd yaw(p.yaw_rad);
  const Eigen::Vector2d ax = yaw * Eigen::Vector2d(p.part->size.x() / 2.0, 0.0);
  const Eigen::Vector2d ay = yaw * Eigen::Vector2d(0.0, p.part->size.y() / 2.0);
  const auto at = [](const Eigen::Vector2d& xy, double z) { return Eigen::Vector3d(xy.x(), xy.y(), z); };
  return {at(p.centre, mid),      at(p.centre, p.z1),      at(p.centre, p.z0),      at(p.centre + ax, mid),
          at(p.centre - ax, mid), at(p.centre + ay, mid), at(p.centre - ay, mid)};
}

bool visible(const SceneRaycaster& raycaster, const Eigen::Vector3d& eye, std::uint32_t object,
             const std::vector<PlacedPart>& parts) {
  for (const PlacedPart& p : parts) {
    for (const Eigen::Vector3d& target : samples(p)) {
      const Eigen::Vector3d ray = target - eye;
      const double distance = ray.norm();
      if (distance <= 0.0) return true;  // the camera is on the object
      // A little beyond the target: a sample on a face is reached even with Embree's float error.
      const auto hit = raycaster.cast(eye, ray / distance, distance * 1.001 + 0.01);
      if (hit && hit->object == object) return true;
    }
  }
  return false;
}

}  // namespace

camera::PinholeCamera pinholeOf(const CameraConfig& c) {
  camera::PinholeCamera p;
  p.name = c.name;
  p.fx = c.fx;
  p.fy = c.fy;
  p.cx = c.cx;
  p.cy = c.cy;
  p.width = c.width;
  p.height = c.height;
  p.world_to_camera = c.pose.inverse();
  return p;
}

Status validate(const TruthReplayConfig& c) {
  if (!(c.miss_rate >= 0.0 && c.miss_rate <= 1.0)) return invalidArgument("truth replay: miss_rate must be in [0, 1]");
  if (!(std::isfinite(c.box_jitter_px) && c.box_jitter_px >= 0.0)) {
    return invalidArgument("truth replay: box_jitter_px must be a finite number of pixels, at least 0");
  }
  if (!(std::isfinite(c.latency_ms) && c.latency_ms >= 0.0)) {
    return invalidArgument("truth replay: latency_ms must be a finite number of milliseconds, at least 0");
  }
  return {};
}

Expected<TruthDetectionFrame> truthDetections(const Scene& scene, const SceneRaycaster& raycaster,
                                              const CameraConfig& camera, std::uint64_t frame,
                                              const TruthReplayConfig& config) {
  if (Status s = validate(config); !s) return s.error();
  const camera::PinholeCamera pinhole = pinholeOf(camera);
  if (Status s = camera::validate(pinhole); !s) return s.error();
  const double time_s = raycaster.time();
  TruthDetectionFrame out;
  out.camera = camera.name;
  out.capture_time_ns = static_cast<std::int64_t>(std::llround(time_s * 1e9));
  out.arrival_time_ns = out.capture_time_ns + static_cast<std::int64_t>(std::llround(config.latency_ms * 1e6));
  const Eigen::Vector3d eye = camera.pose.translation();
  const double width = camera.width;
  const double height = camera.height;

  for (const SceneObject& object : scene.objects) {
    if (object.parts.empty()) continue;
    const std::vector<PlacedPart> parts = placeParts(scene, object, time_s);
    camera::Box2d box{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
                      -std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
    bool in_front = true;
    for (const PlacedPart& p : parts) {
      for (const Eigen::Vector3d& point : outline(p)) {
        const auto pixel = pinhole.project(point, kNearM);
        // Part of the object behind the camera: its box would need clipping in 3D; such an object
        // stands around the camera itself, where no detector boxes it either.
        if (!pixel) {
          in_front = false;
          break;
        }
        box.left = std::min(box.left, pixel->x());
        box.right = std::max(box.right, pixel->x());
        box.top = std::min(box.top, pixel->y());
        box.bottom = std::max(box.bottom, pixel->y());
      }
      if (!in_front) break;
    }
    if (!in_front) continue;

    const Draws draws(config.seed, camera.name, frame, object.id);
    if (config.box_jitter_px > 0.0) {
      box.left += config.box_jitter_px * draws.gaussian(0);
      box.top += config.box_jitter_px * draws.gaussian(1);
      box.right += config.box_jitter_px * draws.gaussian(2);
      box.bottom += config.box_jitter_px * draws.gaussian(3);
      if (box.left > box.right) std::swap(box.left, box.right);
      if (box.top > box.bottom) std::swap(box.top, box.bottom);
    }
    const camera::Box2d clipped{std::clamp(box.left, 0.0, width), std::clamp(box.top, 0.0, height),
                                std::clamp(box.right, 0.0, width), std::clamp(box.bottom, 0.0, height)};
    if (!(clipped.width() > 0.0 && clipped.height() > 0.0)) continue;  // outside the image
    if (!visible(raycaster, eye, object.id, parts)) continue;
    if (draws.uniform(0) < config.miss_rate) continue;

    camera::Detection d;
    d.box = clipped;
    d.label = object.label;
    d.score = 1.0;
    d.camera = camera.name;
    d.capture_time_ns = out.capture_time_ns;
    out.detections.push_back(std::move(d));
    out.objects.push_back(object.id);
  }
  return out;
}

}  // namespace fogmap::sim
