#include "common/camera/pinhole.hpp"

#include <cmath>

namespace fogmap::camera {

std::optional<Eigen::Vector2d> PinholeCamera::project(const Eigen::Vector3d& world, double near_m) const {
  const Eigen::Vector3d p = toCamera(world);
  if (!(p.z() >= near_m)) return std::nullopt;
  double x = p.x() / p.z();
  double y = p.y() / p.z();
  if (!distortion.none()) {
    const auto& d = distortion;
    const double r2 = x * x + y * y;
    const double radial = 1.0 + r2 * (d.k1 + r2 * (d.k2 + r2 * d.k3));
    const double xd = x * radial + 2.0 * d.p1 * x * y + d.p2 * (r2 + 2.0 * x * x);
    const double yd = y * radial + d.p1 * (r2 + 2.0 * y * y) + 2.0 * d.p2 * x * y;
    x = xd;
    y = yd;
  }
  return Eigen::Vector2d(fx * x + cx, fy * y + cy);
}

bool PinholeCamera::inImage(const Eigen::Vector2d& pixel) const {
  return pixel.x() >= 0.0 && pixel.y() >= 0.0 && pixel.x() < width && pixel.y() < height;
}

Status validate(const PinholeCamera& camera) {
  const std::string where = "camera '" + camera.name + "': ";
  const auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!positive(camera.fx) || !positive(camera.fy)) return invalidArgument(where + "fx and fy must be positive focal lengths in pixels");
  if (!std::isfinite(camera.cx) || !std::isfinite(camera.cy)) return invalidArgument(where + "cx and cy must be finite");
  if (camera.width <= 0 || camera.height <= 0) return invalidArgument(where + "width and height must be positive");
  const auto& d = camera.distortion;
  for (const double v : {d.k1, d.k2, d.p1, d.p2, d.k3}) {
    if (!std::isfinite(v)) return invalidArgument(where + "distortion coefficients must be finite");
  }
  if (!camera.world_to_camera.matrix().allFinite()) return invalidArgument(where + "the extrinsics must be finite");
  return {};
}

}  // namespace fogmap::camera
