#include "common/sim/raycaster.hpp"

#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <functional>
#include <thread>

#include "common/base/angles.hpp"
#include "common/sim/counter_random.hpp"

namespace fogmap::sim {
namespace {

// A vertical capped cylinder in scene coordinates.
struct Cylinder {
  Eigen::Vector2d axis_xy;
  double z0 = 0.0, z1 = 1.0, radius = 0.5;
  std::uint32_t object = 0;
};

// The smallest t in (t_min, t_max) where origin + t dir meets the cylinder (side or caps), and the
// normal there.
std::optional<std::pair<double, Eigen::Vector3d>> intersectCylinder(const Cylinder& c, const Eigen::Vector3d& o,
                                                                     const Eigen::Vector3d& d, double t_min,
                                                                     double t_max) {
  std::optional<std::pair<double, Eigen::Vector3d>> best;
  auto consider = [&](double t, const Eigen::Vector3d& n) {
    if (t > t_min && t < t_max && (!best || t < best->first)) best = {t, n};
  };
  // Side: |(o + t d)_xy - c|^2 = r^2.
  const Eigen::Vector2d oc = o.head<2>() - c.axis_xy;
  const Eigen::Vector2d dxy = d.head<2>();
  const double a = dxy.squaredNorm();
  if (a > 0.0) {
    const double b = oc.dot(dxy);
    const double cc = oc.squaredNorm() - c.radius * c.radius;
    const double disc = b * b - a * cc;
    if (disc >= 0.0) {
      const double root = std::sqrt(disc);
      for (const double t : {(-b - root) / a, (-b + root) / a}) {
        const double z = o.z() + t * d.z();
        if (z >= c.z0 && z <= c.z1) {
          const Eigen::Vector2d n = oc + t * dxy;
          consider(t, Eigen::Vector3d(n.x(), n.y(), 0.0));
        }
      }
    }
  }
  // Caps: z = z0 (facing down) and z = z1 (facing up).
  if (d.z() != 0.0) {
    for (const auto& [z, nz] : {std::pair{c.z0, -1.0}, std::pair{c.z1, 1.0}}) {
      const double t = (z - o.z()) / d.z();
      const Eigen::Vector2d p = o.head<2>() + t * dxy;
      if ((p - c.axis_xy).squaredNorm() <= c.radius * c.radius) consider(t, Eigen::Vector3d(0.0, 0.0, nz));
    }
  }
  return best;
}

void cylinderBounds(const RTCBoundsFunctionArguments* args) {
  const auto* cylinders = static_cast<const std::vector<Cylinder>*>(args->geometryUserPtr);
  const Cylinder& c = (*cylinders)[args->primID];
  RTCBounds* b = args->bounds_o;
  b->lower_x = static_cast<float>(c.axis_xy.x() - c.radius);
  b->lower_y = static_cast<float>(c.axis_xy.y() - c.radius);
  b->lower_z = static_cast<float>(c.z0);
  b->upper_x = static_cast<float>(c.axis_xy.x() + c.radius);
  b->upper_y = static_cast<float>(c.axis_xy.y() + c.radius);
  b->upper_z = static_cast<float>(c.z1);
}

// Embree calls these for single rays (N = 1) and packets (N = 4, 8, 16); `valid` marks the lanes.
void cylinderIntersect(const RTCIntersectFunctionNArguments* args) {
  const auto* cylinders = static_cast<const std::vector<Cylinder>*>(args->geometryUserPtr);
  const unsigned n = args->N;
  RTCRayN* rays = RTCRayHitN_RayN(args->rayhit, n);
  RTCHitN* hits = RTCRayHitN_HitN(args->rayhit, n);
  for (unsigned i = 0; i < n; ++i) {
    if (args->valid[i] == 0) continue;
    const Eigen::Vector3d o(RTCRayN_org_x(rays, n, i), RTCRayN_org_y(rays, n, i), RTCRayN_org_z(rays, n, i));
    const Eigen::Vector3d d(RTCRayN_dir_x(rays, n, i), RTCRayN_dir_y(rays, n, i), RTCRayN_dir_z(rays, n, i));
    const auto hit = intersectCylinder((*cylinders)[args->primID], o, d, RTCRayN_tnear(rays, n, i), RTCRayN_tfar(rays, n, i));
    if (!hit) continue;
    RTCRayN_tfar(rays, n, i) = static_cast<float>(hit->first);
    RTCHitN_Ng_x(hits, n, i) = static_cast<float>(hit->second.x());
    RTCHitN_Ng_y(hits, n, i) = static_cast<float>(hit->second.y());
    RTCHitN_Ng_z(hits, n, i) = static_cast<float>(hit->second.z());
    RTCHitN_u(hits, n, i) = 0.0F;
    RTCHitN_v(hits, n, i) = 0.0F;
    RTCHitN_primID(hits, n, i) = args->primID;
    RTCHitN_geomID(hits, n, i) = args->geomID;
    RTCHitN_instID(hits, n, i, 0) = args->context->instID[0];
  }
}

void cylinderOccluded(const RTCOccludedFunctionNArguments* args) {
  const auto* cylinders = static_cast<const std::vector<Cylinder>*>(args->geometryUserPtr);
  const unsigned n = args->N;
  RTCRayN* rays = args->ray;
  for (unsigned i = 0; i < n; ++i) {
    if (args->valid[i] == 0) continue;
    const Eigen::Vector3d o(RTCRayN_org_x(rays, n, i), RTCRayN_org_y(rays, n, i), RTCRayN_org_z(rays, n, i));
    const Eigen::Vector3d d(RTCRayN_dir_x(rays, n, i), RTCRayN_dir_y(rays, n, i), RTCRayN_dir_z(rays, n, i));
    if (intersectCylinder((*cylinders)[args->primID], o, d, RTCRayN_tnear(rays, n, i), RTCRayN_tfar(rays, n, i))) {
      RTCRayN_tfar(rays, n, i) = -std::numeric_limits<float>::infinity();
    }
  }
}

// Counter-based random numbers (counter_random.hpp): the same (seed, frame, lidar, ray) gives the same draws on any thread.
double unitUniform(std::uint64_t bits) { return (static_cast<double>(bits >> 11) + 0.5) * 0x1.0p-53; }

}  // namespace

struct SceneRaycaster::Impl {
  double time_s = 0.0;
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  unsigned triangles_geometry = RTC_INVALID_GEOMETRY_ID;
  unsigned cylinders_geometry = RTC_INVALID_GEOMETRY_ID;
  std::vector<std::uint32_t> triangle_object;  // per triangle
  std::vector<Cylinder> cylinders;             // user geometry data (address stable once built)

  ~Impl() {
    if (scene != nullptr) rtcReleaseScene(scene);
    if (device != nullptr) rtcReleaseDevice(device);
  }
};

SceneRaycaster::SceneRaycaster(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
SceneRaycaster::SceneRaycaster(SceneRaycaster&&) noexcept = default;
SceneRaycaster& SceneRaycaster::operator=(SceneRaycaster&&) noexcept = default;
SceneRaycaster::~SceneRaycaster() = default;

double SceneRaycaster::time() const { return impl_->time_s; }

Eigen::Vector3d beamDirection(double elevation_deg, int step, int azimuth_steps) {
  const double azimuth = 2.0 * M_PI * static_cast<double>(step) / static_cast<double>(azimuth_steps);
  const double e = elevation_deg * kDegToRad;
  return {std::cos(e) * std::cos(azimuth), std::cos(e) * std::sin(azimuth), std::sin(e)};
}

Expected<SceneRaycaster> SceneRaycaster::build(const Scene& scene, double time_s) {
  if (!std::isfinite(time_s)) return invalidArgument("sim: the scene time must be finite");
  auto impl = std::make_unique<Impl>();
  impl->time_s = time_s;
  impl->device = rtcNewDevice("threads=1");
  if (impl->device == nullptr) return Error{ErrorCode::kInternal, "sim: Embree could not make a device"};
  impl->scene = rtcNewScene(impl->device);
  rtcSetSceneBuildQuality(impl->scene, RTC_BUILD_QUALITY_MEDIUM);

  std::vector<Eigen::Vector3f> vertices;
  std::vector<std::array<unsigned, 3>> triangles;
  auto quad = [&](const std::array<Eigen::Vector3d, 4>& corners, std::uint32_t object) {
    const auto base = static_cast<unsigned>(vertices.size());
    for (const auto& c : corners) vertices.push_back(c.cast<float>());
    triangles.push_back({base, base + 1, base + 2});
    triangles.push_back({base, base + 2, base + 3});
    impl->triangle_object.push_back(object);
    impl->triangle_object.push_back(object);
  };

  // The ground: one plane, or two with the riser of the step between them.
  const double L = scene.extent_m;
  const Ground& g = scene.ground;
  auto plane = [&](double x) { return g.height_m + std::tan(g.tilt_deg * kDegToRad) * x; };  // without the step
  auto groundQuad = [&](double x0, double x1, double lift) {
    quad({Eigen::Vector3d(x0, -L, plane(x0) + lift), Eigen::Vector3d(x1, -L, plane(x1) + lift),
          Eigen::Vector3d(x1, L, plane(x1) + lift), Eigen::Vector3d(x0, L, plane(x0) + lift)},
         kGroundId);
  };
  if (g.step_x_m && *g.step_x_m > -L && *g.step_x_m < L) {
    const double s = *g.step_x_m;
    const double base = plane(s);
    groundQuad(-L, s, 0.0);
    groundQuad(s, L, g.step_height_m);
    quad({Eigen::Vector3d(s, -L, base), Eigen::Vector3d(s, L, base), Eigen::Vector3d(s, L, base + g.step_height_m),
          Eigen::Vector3d(s, -L, base + g.step_height_m)},
         kGroundId);
  } else {
    groundQuad(-L, L, g.step_x_m && *g.step_x_m <= -L ? g.step_height_m : 0.0);
  }

  for (const SceneObject& object : scene.objects) {
    const ObjectPose pose = poseAt(object, time_s);
    const Eigen::Rotation2Dd heading(pose.yaw_rad);
    // Objects stand on the ground where their origin is.
    const double ground_z = g.heightAt(pose.xy.x());
    for (const Part& part : object.parts) {
      const Eigen::Vector2d centre = pose.xy + heading * part.at.head<2>();
      const double z0 = ground_z + part.at.z();
      if (part.shape == Shape::kCylinder) {
        impl->cylinders.push_back({centre, z0, z0 + part.size.z(), part.size.x() / 2.0, object.id});
        continue;
      }
      const Eigen::Rotation2Dd yaw(pose.yaw_rad + part.yaw_deg * kDegToRad);
      const Eigen::Vector2d ax = yaw * Eigen::Vector2d(part.size.x() / 2.0, 0.0);
      const Eigen::Vector2d ay = yaw * Eigen::Vector2d(0.0, part.size.y() / 2.0);
      const double z1 = z0 + part.size.z();
      auto corner = [&](double sx, double sy, double z) {
        const Eigen::Vector2d p = centre + sx * ax + sy * ay;
        return Eigen::Vector3d(p.x(), p.y(), z);
      };
      for (const double z : {z0, z1}) {  // bottom and top
        quad({corner(-1, -1, z), corner(1, -1, z), corner(1, 1, z), corner(-1, 1, z)}, object.id);
      }
      const std::array<std::pair<double, double>, 4> around = {{{-1, -1}, {1, -1}, {1, 1}, {-1, 1}}};
      for (std::size_t i = 0; i < 4; ++i) {
        const auto [sx0, sy0] = around[i];
        const auto [sx1, sy1] = around[(i + 1) % 4];
        quad({corner(sx0, sy0, z0), corner(sx1, sy1, z0), corner(sx1, sy1, z1), corner(sx0, sy0, z1)}, object.id);
      }
    }
  }

  RTCGeometry mesh = rtcNewGeometry(impl->device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* vb = static_cast<float*>(
      rtcSetNewGeometryBuffer(mesh, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), vertices.size()));
  auto* ib = static_cast<unsigned*>(
      rtcSetNewGeometryBuffer(mesh, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), triangles.size()));
  if (vb == nullptr || ib == nullptr) {
    rtcReleaseGeometry(mesh);
    return Error{ErrorCode::kResourceExhausted, "sim: Embree could not allocate the scene's triangles"};
  }
  for (std::size_t i = 0; i < vertices.size(); ++i) {
    vb[3 * i] = vertices[i].x();
    vb[3 * i + 1] = vertices[i].y();
    vb[3 * i + 2] = vertices[i].z();
  }
  for (std::size_t i = 0; i < triangles.size(); ++i) std::copy(triangles[i].begin(), triangles[i].end(), ib + 3 * i);
  rtcCommitGeometry(mesh);
  impl->triangles_geometry = rtcAttachGeometry(impl->scene, mesh);
  rtcReleaseGeometry(mesh);

  if (!impl->cylinders.empty()) {
    RTCGeometry user = rtcNewGeometry(impl->device, RTC_GEOMETRY_TYPE_USER);
    rtcSetGeometryUserPrimitiveCount(user, static_cast<unsigned>(impl->cylinders.size()));
    rtcSetGeometryUserData(user, &impl->cylinders);
    rtcSetGeometryBoundsFunction(user, cylinderBounds, nullptr);
    rtcSetGeometryIntersectFunction(user, cylinderIntersect);
    rtcSetGeometryOccludedFunction(user, cylinderOccluded);
    rtcCommitGeometry(user);
    impl->cylinders_geometry = rtcAttachGeometry(impl->scene, user);
    rtcReleaseGeometry(user);
  }
  rtcCommitScene(impl->scene);
  if (rtcGetDeviceError(impl->device) != RTC_ERROR_NONE) {
    return Error{ErrorCode::kInternal, "sim: Embree could not build the scene"};
  }
  return SceneRaycaster(std::move(impl));
}

std::optional<Hit> SceneRaycaster::cast(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                                        double max_range_m) const {
  const Eigen::Vector3d d = direction.normalized();
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit rh{};
  rh.ray.org_x = static_cast<float>(origin.x());
  rh.ray.org_y = static_cast<float>(origin.y());
  rh.ray.org_z = static_cast<float>(origin.z());
  rh.ray.dir_x = static_cast<float>(d.x());
  rh.ray.dir_y = static_cast<float>(d.y());
  rh.ray.dir_z = static_cast<float>(d.z());
  rh.ray.tnear = 0.0F;
  rh.ray.tfar = static_cast<float>(max_range_m);
  rh.ray.mask = 0xFFFFFFFFU;
  rh.ray.flags = 0;
  rh.ray.time = 0.0F;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(impl_->scene, &context, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return std::nullopt;
  Hit hit;
  hit.distance_m = rh.ray.tfar;
  hit.normal = Eigen::Vector3d(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z);
  hit.object = rh.hit.geomID == impl_->triangles_geometry ? impl_->triangle_object[rh.hit.primID]
                                                           : impl_->cylinders[rh.hit.primID].object;
  return hit;
}

Expected<SimFrame> SceneRaycaster::scan(const LidarConfig& lidar, std::uint64_t seed, std::uint64_t frame,
                                        int threads) const {
  auto model = lidarModel(lidar.model);
  if (!model) return model.error();
  const int steps = lidar.azimuth_steps.value_or(model->azimuth_steps);
  const double min_range = lidar.min_range_m.value_or(model->min_range_m);
  const double max_range = lidar.max_range_m.value_or(model->max_range_m);
  const int rings = model->rings();
  const std::size_t rays = static_cast<std::size_t>(rings) * static_cast<std::size_t>(steps);
  const std::uint64_t stream = mix(mix(seed) ^ mix(frame + 0x51ED2701ULL) ^ nameHash(lidar.name));

  // Directions in the sensor frame from one sin/cos per ring and per azimuth step.
  std::vector<double> cos_e(rings), sin_e(rings), cos_a(steps), sin_a(steps);
  for (int r = 0; r < rings; ++r) {
    cos_e[r] = std::cos(model->elevations_deg[r] * kDegToRad);
    sin_e[r] = std::sin(model->elevations_deg[r] * kDegToRad);
  }
  for (int s = 0; s < steps; ++s) {
    const double azimuth = 2.0 * M_PI * static_cast<double>(s) / static_cast<double>(steps);
    cos_a[s] = std::cos(azimuth);
    sin_a[s] = std::sin(azimuth);
  }
  const auto direction = [&](std::size_t i) {
    const std::size_t r = i / static_cast<std::size_t>(steps);
    const std::size_t a = i % static_cast<std::size_t>(steps);
    return Eigen::Vector3d(cos_e[r] * cos_a[a], cos_e[r] * sin_a[a], sin_e[r]);
  };
  const Eigen::Vector3d origin = lidar.pose.translation();
  const Eigen::Matrix3d rotation = lidar.pose.rotation();
  struct Returns {
    Cloud points;
    std::vector<std::uint32_t> truth;
  };
  // Packets of 8 neighbouring rays of one ring: coherent, so Embree traverses them together.
  constexpr std::size_t kPacket = 8;
  // Rays [first, last) in order into `out`.
  auto work = [&](std::size_t first, std::size_t last, Returns& out) {
    out.points.reserve((last - first) * 3 / 4);
    out.truth.reserve((last - first) * 3 / 4);
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    for (std::size_t start = first; start < last; start += kPacket) {
      alignas(32) int valid[kPacket];
      alignas(32) RTCRayHit8 packet;
      for (std::size_t lane = 0; lane < kPacket; ++lane) {
        const std::size_t i = start + lane;
        valid[lane] = i < last ? -1 : 0;
        const Eigen::Vector3d dir = rotation * direction(std::min(i, last - 1));
        packet.ray.org_x[lane] = static_cast<float>(origin.x());
        packet.ray.org_y[lane] = static_cast<float>(origin.y());
        packet.ray.org_z[lane] = static_cast<float>(origin.z());
        packet.ray.dir_x[lane] = static_cast<float>(dir.x());
        packet.ray.dir_y[lane] = static_cast<float>(dir.y());
        packet.ray.dir_z[lane] = static_cast<float>(dir.z());
        packet.ray.tnear[lane] = 0.0F;
        packet.ray.tfar[lane] = static_cast<float>(max_range);
        packet.ray.time[lane] = 0.0F;
        packet.ray.mask[lane] = 0xFFFFFFFFU;
        packet.ray.id[lane] = static_cast<unsigned>(lane);
        packet.ray.flags[lane] = 0;
        packet.hit.geomID[lane] = RTC_INVALID_GEOMETRY_ID;
        packet.hit.instID[0][lane] = RTC_INVALID_GEOMETRY_ID;
      }
      rtcIntersect8(valid, impl_->scene, &context, &packet);
      for (std::size_t lane = 0; lane < kPacket && start + lane < last; ++lane) {
        const std::size_t i = start + lane;
        const unsigned geom = packet.hit.geomID[lane];
        if (geom == RTC_INVALID_GEOMETRY_ID) continue;
        const std::uint32_t object = geom == impl_->triangles_geometry ? impl_->triangle_object[packet.hit.primID[lane]]
                                                                        : impl_->cylinders[packet.hit.primID[lane]].object;
        const std::uint64_t bits = mix(stream ^ mix(i));
        if (lidar.dropout > 0.0 && unitUniform(bits) < lidar.dropout) continue;
        // Box-Muller from two more draws of the ray's stream.
        double noise = 0.0;
        if (lidar.range_noise_m > 0.0) {
          const double u1 = unitUniform(mix(bits ^ 0x1ULL));
          const double u2 = unitUniform(mix(bits ^ 0x2ULL));
          noise = lidar.range_noise_m * std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
        }
        const double range = static_cast<double>(packet.ray.tfar[lane]) + noise;
        if (range < min_range || range > max_range) continue;
        const Eigen::Vector3d p = direction(i) * range;
        out.points.push_back({static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()), 0.0F});
        out.truth.push_back(object);
      }
    }
  };
  // Contiguous ranges of rays per thread, joined in order: the same frame whatever the count.
  const int workers = std::clamp(threads, 1, 64);
  std::vector<Returns> parts(static_cast<std::size_t>(workers));
  if (workers == 1) {
    work(0, rays, parts[0]);
  } else {
    std::vector<std::thread> pool;
    const std::size_t per = (rays + workers - 1) / workers;
    for (int w = 0; w < workers; ++w) {
      const std::size_t first = std::min(rays, w * per);
      pool.emplace_back(work, first, std::min(rays, first + per), std::ref(parts[static_cast<std::size_t>(w)]));
    }
    for (auto& t : pool) t.join();
  }

  SimFrame out;
  out.lidar = lidar.name;
  out.time_s = impl_->time_s;
  out.sensor_pose = lidar.pose;
  out.rays = rays;
  out.points = std::move(parts[0].points);
  out.truth = std::move(parts[0].truth);
  for (std::size_t w = 1; w < parts.size(); ++w) {
    out.points.insert(out.points.end(), parts[w].points.begin(), parts[w].points.end());
    out.truth.insert(out.truth.end(), parts[w].truth.begin(), parts[w].truth.end());
  }
  return out;
}

}  // namespace fogmap::sim
