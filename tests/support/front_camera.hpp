#pragma once
// The tracker tests' camera: "cam-1" at (0, 0, 1) looking along +x (default intrinsics).
#include <Eigen/Core>

#include "common/camera/pinhole.hpp"

namespace fogmap::test_support {

inline camera::PinholeCamera frontCamera() {
  camera::PinholeCamera cam;
  cam.name = "cam-1";
  Eigen::Matrix3d r;
  r << 0, -1, 0, 0, 0, -1, 1, 0, 0;
  cam.world_to_camera.linear() = r;
  cam.world_to_camera.translation() = -r * Eigen::Vector3d(0, 0, 1);
  return cam;
}

}  // namespace fogmap::test_support
