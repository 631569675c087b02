#include "common/sim/generators.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <optional>
#include <random>

#include <Eigen/Geometry>

#include "common/sim/footprint.hpp"

namespace fogmap::sim {
namespace {

Part box(double x, double y, double z, Eigen::Vector3d at = Eigen::Vector3d::Zero()) {
  return {Shape::kBox, at, {x, y, z}, 0.0};
}
Part cylinder(double radius, double height, Eigen::Vector3d at = Eigen::Vector3d::Zero()) {
  return {Shape::kCylinder, at, {2 * radius, 2 * radius, height}, 0.0};
}

// The catalogue of the random scenes (the paper's: from 0.8 m crates to cars; trucks in the
// factory and by hand): label, parts, and the radius of a circle that holds them.
struct Kind {
  std::string label;
  std::vector<Part> parts;
  double radius;
};

const std::vector<Kind>& catalogue() {
  static const std::vector<Kind> kinds = {
      {"crate", {box(0.8, 0.8, 0.8)}, 0.57},
      {"pallet", {box(1.2, 1.0, 1.4)}, 0.79},
      {"person", {cylinder(0.25, 1.75)}, 0.25},
      {"pole", {cylinder(0.12, 3.0)}, 0.12},
      {"car", {box(4.4, 1.8, 0.9, {0, 0, 0.25}), box(2.2, 1.6, 0.55, {-0.3, 0, 1.15})}, 2.4},
  };
  return kinds;
}

Eigen::Isometry3d sensorPose(const Eigen::Vector3d& position, double yaw_rad) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  pose.translation() = position;
  return pose;
}

// Places `radius` at random in [-half, half]^2 away from every circle in `taken` by `gap`; false
// after many tries (the area is full).
bool place(std::mt19937_64& rng, double half, double radius, double gap, std::vector<std::pair<Eigen::Vector2d, double>>& taken,
           Eigen::Vector2d& out) {
  std::uniform_real_distribution<double> coord(-half + radius, half - radius);
  for (int attempt = 0; attempt < 2000; ++attempt) {
    const Eigen::Vector2d p(coord(rng), coord(rng));
    bool free = true;
    for (const auto& [c, r] : taken) free = free && (p - c).norm() >= r + radius + gap;
    if (!free) continue;
    taken.emplace_back(p, radius);
    out = p;
    return true;
  }
  return false;
}

}  // namespace

Eigen::Isometry3d lookAt(const Eigen::Vector3d& position, const Eigen::Vector3d& target) {
  const Eigen::Vector3d forward = (target - position).normalized();
  Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitZ());
  if (right.norm() < 1e-9) right = Eigen::Vector3d::UnitX();
  right.normalize();
  const Eigen::Vector3d down = forward.cross(right);
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear().col(0) = right;
  pose.linear().col(1) = down;
  pose.linear().col(2) = forward;
  pose.translation() = position;
  return pose;
}

std::vector<LidarConfig> lidarSpots(int count, double half_m, const std::string& model) {
  const std::vector<Eigen::Vector2d> spots = {{-half_m, -half_m}, {half_m, half_m}, {half_m, -half_m}, {-half_m, half_m},
                                              {0.0, -half_m},     {0.0, half_m},    {0.0, 0.0}};
  std::vector<LidarConfig> out;
  for (int i = 0; i < std::min<int>(count, static_cast<int>(spots.size())); ++i) {
    LidarConfig l;
    l.name = "lidar-" + std::to_string(i + 1);
    l.model = model;
    const Eigen::Vector2d at = spots[static_cast<std::size_t>(i)];
    const double yaw = at.isZero() ? 0.0 : std::atan2(-at.y(), -at.x());
    l.pose = sensorPose({at.x(), at.y(), 1.8}, yaw);
    out.push_back(l);
  }
  return out;
}

// A scene over a square area of half-size `half` (the ground reaching 15 m beyond it) watched by
// `lidars` LiDARs of `model` at the paper's spots.
Scene areaScene(std::string name, std::uint64_t seed, double half, int lidars, const std::string& model) {
  Scene scene;
  scene.name = std::move(name);
  scene.seed = seed;
  scene.extent_m = half + 15.0;
  scene.lidars = lidarSpots(lidars, half, model);
  return scene;
}

Scene randomScene(int objects, int lidars, std::uint64_t seed) {
  constexpr double kHalf = 25.0;
  Scene scene = areaScene("random-" + std::to_string(objects) + "-l" + std::to_string(lidars) + "-s" + std::to_string(seed),
                          seed, kHalf, lidars, "HDL-32E");
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<std::size_t> kind(0, catalogue().size() - 1);
  std::uniform_real_distribution<double> yaw(-180.0, 180.0);
  std::vector<std::pair<Eigen::Vector2d, double>> taken;
  for (const LidarConfig& l : scene.lidars) taken.emplace_back(l.pose.translation().head<2>(), 1.0);
  for (int i = 0; i < objects; ++i) {
    // A kind that no longer fits gives way to a smaller one: the count is what the caller asked.
    const Kind* k = &catalogue()[kind(rng)];
    SceneObject o;
    bool placed = place(rng, kHalf, k->radius, 1.0, taken, o.xy);
    for (std::size_t smaller = 0; !placed && smaller < catalogue().size(); ++smaller) {
      if (catalogue()[smaller].radius >= k->radius) continue;
      k = &catalogue()[smaller];
      placed = place(rng, kHalf, k->radius, 1.0, taken, o.xy);
    }
    if (!placed) break;  // the area is full
    o.id = static_cast<std::uint32_t>(i + 1);
    o.label = k->label;
    o.name = k->label + "-" + std::to_string(i + 1);
    o.parts = k->parts;
    o.yaw_deg = yaw(rng);
    scene.objects.push_back(o);
  }
  return scene;
}

Scene factoryScene(std::uint64_t seed) {
  Scene scene;
  scene.name = "factory-s" + std::to_string(seed);
  scene.seed = seed;
  constexpr double kHalf = 20.0;
  scene.extent_m = kHalf + 5.0;
  scene.lidars = lidarSpots(4, kHalf, "HDL-32E");
  auto middle = lidarSpots(7, kHalf, "HDL-32E").back();
  middle.name = "lidar-5";
  middle.pose.translation().z() = 4.0;  // above the shelves
  scene.lidars.push_back(middle);
  std::mt19937_64 rng(seed);
  std::uint32_t id = 1;
  auto add = [&](const std::string& label, std::vector<Part> parts, Eigen::Vector2d xy, double yaw_deg, Motion motion = {}) {
    SceneObject o;
    o.id = id++;
    o.label = label;
    o.name = label + "-" + std::to_string(o.id);
    o.parts = std::move(parts);
    o.xy = xy;
    o.yaw_deg = yaw_deg;
    o.motion = std::move(motion);
    scene.objects.push_back(std::move(o));
  };
  // Two rows of shelves along x, aisles between them.
  for (const double y : {-9.0, -3.0, 3.0, 9.0}) {
    for (const double x : {-10.0, 2.0}) add("shelf", {box(8.0, 1.2, 2.5)}, {x, y}, 0.0);
  }
  // Forklifts drive the aisles (body and mast), back and forth.
  std::uniform_real_distribution<double> speed(1.0, 2.0);
  for (const double y : {0.0, 6.0, -6.0}) {
    Motion m;
    m.waypoints = {{-15.0, y}, {12.0, y}};
    m.speed_mps = speed(rng);
    m.loop = true;
    add("forklift", {box(2.2, 1.2, 1.3), box(0.25, 1.0, 2.3, {1.2, 0, 0})}, {-15.0, y}, 0.0, m);
  }
  // People walk across the hall.
  std::uniform_real_distribution<double> cross(-14.0, 14.0);
  for (int i = 0; i < 4; ++i) {
    Motion m;
    m.waypoints = {{cross(rng), -16.0}, {cross(rng), 16.0}};
    m.speed_mps = 1.3;
    m.loop = true;
    add("person", {cylinder(0.25, 1.75)}, m.waypoints.front(), 0.0, m);
  }
  // A crane: a pillar and its arm.
  add("crane", {box(0.6, 0.6, 6.0), box(6.0, 0.4, 0.4, {2.7, 0, 5.6})}, {15.0, -15.0}, 135.0);
  return scene;
}

Scene movingScene(int people, int vehicles, int lidars, int cameras, std::uint64_t seed) {
  constexpr double kHalf = 20.0;
  Scene scene = areaScene("moving-p" + std::to_string(people) + "-v" + std::to_string(vehicles) + "-s" + std::to_string(seed),
                          seed, kHalf, lidars, "VLP-16");
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> across(-kHalf * 0.8, kHalf * 0.8);
  std::uniform_real_distribution<double> walk(1.0, 1.6);
  std::uniform_real_distribution<double> drive(3.0, 6.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  auto path = [&](int i) {
    // Even paths run west-east, odd ones south-north, so they cross; the offsets keep some parallel.
    const double offset = across(rng);
    std::vector<Eigen::Vector2d> w = i % 2 == 0 ? std::vector<Eigen::Vector2d>{{-kHalf, offset}, {kHalf, offset}}
                                                 : std::vector<Eigen::Vector2d>{{offset, -kHalf}, {offset, kHalf}};
    return w;
  };
  // Vehicles keep to lanes: a path parallel to another vehicle's lies at least a lane (kLaneM)
  // beside it, its offset drawn again (a bounded number of times) where it would not. Two cars
  // 2 m apart side by side, 0.2 m between their bodies, would collide, and no sensor separates them.
  constexpr double kLaneM = 3.0;
  constexpr int kLaneDraws = 64;
  std::vector<std::vector<Eigen::Vector2d>> vehicle_paths;
  auto lanePath = [&](int i) {
    std::vector<Eigen::Vector2d> w = path(i);
    const int axis = i % 2 == 0 ? 1 : 0;  // the coordinate the offset sets
    auto crowded = [&](const std::vector<Eigen::Vector2d>& candidate) {
      return std::any_of(vehicle_paths.begin(), vehicle_paths.end(), [&](const std::vector<Eigen::Vector2d>& other) {
        const bool parallel = std::abs(other.front()[axis] - other.back()[axis]) < 1e-9;
        return parallel && std::abs(other.front()[axis] - candidate.front()[axis]) < kLaneM;
      });
    };
    for (int draw = 1; draw < kLaneDraws && crowded(w); ++draw) w = path(i);
    return w;
  };
  // Nothing passes through anything: each object goes back and forth along its path from a drawn
  // point of it in a drawn direction, and its body keeps kClearanceM from every object placed
  // before it (kVehicleClearanceM between two vehicles) at every kClearanceStepS of the scene's
  // cycle. Where it would not, its path, start and direction are drawn again, at most
  // kPlacementDraws times; the draw that falls short at the fewest instants stays when none keeps
  // enough. A crowded scene (hundreds of objects) spends at most kSceneDraws draws in all, then
  // places the rest as first drawn. Vehicles are placed first, all at one speed: two on crossing
  // lanes then meet the crossing in a fixed rhythm that a start can keep apart, and people find
  // gaps in the traffic.
  constexpr double kClearanceM = 0.5;
  constexpr double kVehicleClearanceM = 1.0;
  constexpr double kClearanceStepS = 0.02;
  constexpr int kPlacementDraws = 256;
  constexpr int kSceneDraws = 4096;
  std::vector<double> times;
  for (int k = 0; k * kClearanceStepS < scene.duration_s; ++k) times.push_back(k * kClearanceStepS);
  // Where an object's body is over the cycle: its pose at each time and its outline about its pose.
  struct Course {
    bool vehicle = false;
    std::vector<ObjectPose> poses;       // per time
    std::vector<Eigen::Vector2d> local;  // the outline at pose 0
    double radius = 0.0;                 // of a circle about the pose that holds the outline
    std::vector<Eigen::Vector2d> outlineAt(std::size_t k) const {
      const Eigen::Rotation2Dd turn(poses[k].yaw_rad);
      std::vector<Eigen::Vector2d> outline;
      outline.reserve(local.size());
      for (const auto& v : local) outline.push_back(turn * v + poses[k].xy);
      return outline;
    }
  };
  std::vector<Course> placed;
  const auto courseOf = [&](const SceneObject& object, bool vehicle) {
    SceneObject still = object;
    still.motion = Motion{};
    still.xy = Eigen::Vector2d::Zero();
    still.yaw_deg = 0.0;
    Course course;
    course.vehicle = vehicle;
    course.local = footprint(still, 0.0);
    for (const auto& v : course.local) course.radius = std::max(course.radius, v.norm());
    course.poses.reserve(times.size());
    for (const double t : times) course.poses.push_back(poseAt(object, t));
    return course;
  };
  // The instants at which a body falls short of its clearance to a placed one (counted up to `enough`).
  const auto shortInstants = [&](const Course& course, std::size_t enough) {
    std::size_t count = 0;
    for (const Course& other : placed) {
      const double keep = course.vehicle && other.vehicle ? kVehicleClearanceM : kClearanceM;
      const double apart = course.radius + other.radius + keep;
      for (std::size_t k = 0; k < times.size() && count < enough; ++k) {
        if ((course.poses[k].xy - other.poses[k].xy).squaredNorm() >= apart * apart) continue;
        if (footprintGap(course.outlineAt(k), other.outlineAt(k)) < keep) ++count;
      }
    }
    return count;
  };
  int scene_draws = 0;
  const auto place = [&](SceneObject& o, bool vehicle, const std::function<std::vector<Eigen::Vector2d>()>& drawPath) {
    std::optional<std::pair<std::size_t, SceneObject>> best;
    Course best_course;
    for (int draw = 0; draw < kPlacementDraws; ++draw) {
      const std::vector<Eigen::Vector2d> ends = drawPath();
      const Eigen::Vector2d start = ends[0] + unit(rng) * (ends[1] - ends[0]);
      const bool forward = unit(rng) < 0.5;
      SceneObject candidate = o;
      candidate.motion.waypoints = forward ? std::vector<Eigen::Vector2d>{start, ends[1], ends[0]}
                                           : std::vector<Eigen::Vector2d>{start, ends[0], ends[1]};
      candidate.xy = start;
      Course course = courseOf(candidate, vehicle);
      const bool last = ++scene_draws > kSceneDraws;
      const std::size_t short_at = last ? 0 : shortInstants(course, best ? best->first : times.size() * (placed.size() + 1));
      if (!best || short_at < best->first) {
        best.emplace(short_at, std::move(candidate));
        best_course = std::move(course);
      }
      if (short_at == 0) break;
    }
    o = std::move(best->second);
    placed.push_back(std::move(best_course));
  };
  const std::uint32_t first_vehicle = static_cast<std::uint32_t>(std::max(people, 0)) + 1;
  const double vehicle_speed = drive(rng);
  std::vector<SceneObject> vehicles_placed;
  for (int i = 0; i < vehicles; ++i) {
    SceneObject o;
    o.id = first_vehicle + static_cast<std::uint32_t>(i);
    o.label = "car";
    o.name = "car-" + std::to_string(o.id);
    o.parts = catalogue()[4].parts;
    o.motion.speed_mps = vehicle_speed;
    o.motion.loop = true;
    place(o, true, [&] { return lanePath(i + 1); });
    const auto& w = o.motion.waypoints;
    vehicle_paths.push_back({w[1], w[2]});
    vehicles_placed.push_back(std::move(o));
  }
  for (int i = 0; i < people; ++i) {
    SceneObject o;
    o.id = static_cast<std::uint32_t>(i) + 1;
    o.label = "person";
    o.name = "person-" + std::to_string(o.id);
    o.parts = {cylinder(0.25, 1.75)};
    o.motion.speed_mps = walk(rng);
    o.motion.loop = true;
    place(o, false, [&] { return path(i); });
    scene.objects.push_back(o);
  }
  for (SceneObject& o : vehicles_placed) scene.objects.push_back(std::move(o));
  const std::vector<Eigen::Vector2d> camera_spots = {{-kHalf - 2, 0}, {kHalf + 2, 0}, {0, -kHalf - 2}, {0, kHalf + 2},
                                                     {-kHalf - 2, -kHalf - 2}, {kHalf + 2, kHalf + 2}};
  for (int i = 0; i < std::min<int>(cameras, static_cast<int>(camera_spots.size())); ++i) {
    CameraConfig c;
    c.name = "camera-" + std::to_string(i + 1);
    const Eigen::Vector2d at = camera_spots[static_cast<std::size_t>(i)];
    c.pose = lookAt({at.x(), at.y(), 4.0}, {0.0, 0.0, 0.5});
    c.width = 640;
    c.height = 480;
    c.fx = c.fy = 420.0;
    c.cx = 320.0;
    c.cy = 240.0;
    scene.cameras.push_back(c);
  }
  return scene;
}

}  // namespace fogmap::sim
