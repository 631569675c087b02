#pragma once
// A calibrated camera: intrinsics (focal lengths and principal point in pixels), the Brown-Conrady
// distortion OpenCV uses (k1, k2, p1, p2, k3) and extrinsics (the common frame to the camera's:
// x right, y down, z forward), with the image size. Projects 3D points of the common frame into
// pixels, as the tracker's overlay needs. Pure.
#include <optional>
#include <span>
#include <string>

#include <Eigen/Geometry>

#include "common/base/status.hpp"
#include "common/camera/detection.hpp"  // Box2d

namespace fogmap::camera {

struct Distortion {
  double k1 = 0.0, k2 = 0.0, p1 = 0.0, p2 = 0.0, k3 = 0.0;
  bool none() const { return k1 == 0.0 && k2 == 0.0 && p1 == 0.0 && p2 == 0.0 && k3 == 0.0; }
};

struct PinholeCamera {
  std::string name;
  double fx = 500.0, fy = 500.0, cx = 320.0, cy = 240.0;  // pixels
  Distortion distortion;
  Eigen::Isometry3d world_to_camera = Eigen::Isometry3d::Identity();
  int width = 640, height = 480;  // pixels

  // The camera's centre in the common frame.
  Eigen::Vector3d centre() const { return world_to_camera.inverse().translation(); }
  // A point of the common frame in the camera's frame.
  Eigen::Vector3d toCamera(const Eigen::Vector3d& world) const { return world_to_camera * world; }
  // The pixel of a point of the common frame, or nothing when it lies less than `near_m` in front
  // of the camera. The pixel may be outside the image; inImage tells.
  std::optional<Eigen::Vector2d> project(const Eigen::Vector3d& world, double near_m = 0.1) const;
  // The pixel of a point (x / z, y / z) of the camera's frame: distorted, then through the intrinsics.
  Eigen::Vector2d pixelOf(const Eigen::Vector2d& normalized) const;
  bool inImage(const Eigen::Vector2d& pixel) const;
};

// The image box around an ellipsoid {x : (x - centre)^T shape^-1 (x - centre) <= 1} of the common
// frame (a MAD-C ellipsoid): exact for a camera without distortion (the outline of the ellipsoid's
// dual quadric), its outline traced and distorted otherwise. Nothing unless the whole ellipsoid lies
// more than `near_m` in front of the camera. The box may reach outside the image.
std::optional<Box2d> projectEllipsoid(const PinholeCamera& camera, const Eigen::Vector3d& centre, const Eigen::Matrix3d& shape,
                                      double near_m = 0.1);

// The image box around the pixels of `points` (the common frame; a 3D box's corners, say): nothing
// unless every point lies more than `near_m` in front of the camera. The box may reach outside the
// image.
std::optional<Box2d> projectPoints(const PinholeCamera& camera, std::span<const Eigen::Vector3d> points, double near_m = 0.1);

// Checks that the intrinsics are finite and positive and the image has pixels; the error names
// the camera and the field.
Status validate(const PinholeCamera& camera);

}  // namespace fogmap::camera
