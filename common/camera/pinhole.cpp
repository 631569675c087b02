#include "common/camera/pinhole.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>

namespace fogmap::camera {

std::optional<Eigen::Vector2d> PinholeCamera::project(const Eigen::Vector3d& world, double near_m) const {
  const Eigen::Vector3d p = toCamera(world);
  if (!(p.z() >= near_m)) return std::nullopt;
  return pixelOf(Eigen::Vector2d(p.x() / p.z(), p.y() / p.z()));
}

std::optional<Box2d> projectPoints(const PinholeCamera& camera, std::span<const Eigen::Vector3d> points, double near_m) {
  if (points.empty()) return std::nullopt;
  Box2d out{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
            -std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
  for (const Eigen::Vector3d& point : points) {
    const auto pixel = camera.project(point, near_m);
    if (!pixel) return std::nullopt;
    out.left = std::min(out.left, pixel->x());
    out.top = std::min(out.top, pixel->y());
    out.right = std::max(out.right, pixel->x());
    out.bottom = std::max(out.bottom, pixel->y());
  }
  return out;
}

Eigen::Vector2d PinholeCamera::pixelOf(const Eigen::Vector2d& normalized) const {
  double x = normalized.x();
  double y = normalized.y();
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

std::optional<Box2d> projectEllipsoid(const PinholeCamera& camera, const Eigen::Vector3d& centre, const Eigen::Matrix3d& shape,
                                      double near_m) {
  // In the camera's frame: the ellipsoid {x : (x - c)^T S^-1 (x - c) <= 1}.
  const Eigen::Matrix3d r = camera.world_to_camera.linear();
  const Eigen::Vector3d c = camera.toCamera(centre);
  const Eigen::Matrix3d s = r * shape * r.transpose();
  if (!c.allFinite() || !s.allFinite()) return std::nullopt;
  // Wholly in front: its nearest point along z, c_z - sqrt(S_zz), beyond near_m.
  if (!(c.z() - std::sqrt(std::max(0.0, s(2, 2))) > near_m)) return std::nullopt;
  // Its dual quadric Q* = [S - c c^T, -c; -c^T, -1] seen through [I | 0] is the dual conic of its
  // outline on the plane z = 1: D = Q*'s rows and columns x, y, 1 (here z is the homogeneous one).
  Eigen::Matrix4d dual;
  dual.topLeftCorner<3, 3>() = s - c * c.transpose();
  dual.topRightCorner<3, 1>() = -c;
  dual.bottomLeftCorner<1, 3>() = -c.transpose();
  dual(3, 3) = -1.0;
  Eigen::Matrix3d d;  // x, y, z of the camera's frame = homogeneous x, y, w of the image plane
  d = dual.topLeftCorner<3, 3>();
  // The same form one dimension down: D ~ [M - m m^T, -m; -m^T, -1] for the outline ellipse
  // {p : (p - m)^T M^-1 (p - m) <= 1} in normalized image coordinates.
  if (!(d(2, 2) < 0.0)) return std::nullopt;
  d /= -d(2, 2);
  const Eigen::Vector2d m = -d.block<2, 1>(0, 2);
  const Eigen::Matrix2d outline = d.topLeftCorner<2, 2>() + m * m.transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> solver(outline);
  if (solver.info() != Eigen::Success || !(solver.eigenvalues().minCoeff() > 0.0)) return std::nullopt;
  Box2d box{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
            -std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
  const auto include = [&box](const Eigen::Vector2d& pixel) {
    box.left = std::min(box.left, pixel.x());
    box.top = std::min(box.top, pixel.y());
    box.right = std::max(box.right, pixel.x());
    box.bottom = std::max(box.bottom, pixel.y());
  };
  if (camera.distortion.none()) {
    // Intrinsics are affine: the box of the outline is the outline's box, m -+ sqrt(diag M), mapped.
    const Eigen::Vector2d half(std::sqrt(outline(0, 0)), std::sqrt(outline(1, 1)));
    include(camera.pixelOf(m - half));
    include(camera.pixelOf(m + half));
    return box;
  }
  // With distortion, the outline traced in 360 steps and each point distorted.
  const Eigen::Matrix2d root = solver.eigenvectors() * solver.eigenvalues().cwiseSqrt().asDiagonal();
  constexpr int kSteps = 360;
  for (int i = 0; i < kSteps; ++i) {
    const double a = 2.0 * M_PI * i / kSteps;
    include(camera.pixelOf(m + root * Eigen::Vector2d(std::cos(a), std::sin(a))));
  }
  return box;
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
