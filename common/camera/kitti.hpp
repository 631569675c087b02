#pragma once
// KITTI's camera calibration and object labels (the object benchmark's calib/ and label_2/ files)
// and the projection of 3D points and boxes into an image: the first piece of common/camera, pure.
//
// Frames: a LiDAR point x_velo goes to the rectified camera frame as R0_rect * Tr_velo_to_cam *
// x_velo (x right, y down, z forward); camera i's image is P_i * x_rect (homogeneous). Labels give
// boxes in the rectified camera frame: the centre of the bottom face, height, width, length and the
// yaw about the camera's y axis.
#include <array>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "common/base/status.hpp"
#include "common/camera/detection.hpp"  // Box2d
#include "common/camera/pinhole.hpp"

namespace fogmap::camera {

struct KittiCalibration {
  std::array<Eigen::Matrix<double, 3, 4>, 4> projection;  // P0..P3: rectified frame -> image i
  Eigen::Matrix3d rectification = Eigen::Matrix3d::Identity();  // R0_rect
  Eigen::Isometry3d velodyne_to_camera = Eigen::Isometry3d::Identity();  // Tr_velo_to_cam

  // A LiDAR point in the rectified camera frame.
  Eigen::Vector3d velodyneToRectified(const Eigen::Vector3d& point) const;
};

// Camera `index` (0..3) of a calibration as a pinhole camera whose common frame is the Velodyne's
// (KITTI's rectified images: no distortion), for a width x height image: it projects a LiDAR point
// to the same pixel as projectPoint(projection[index], velodyneToRectified(point)). An error when
// the index is out of range or P_index is not K [I | t] with K upper triangular and focal lengths
// positive.
Expected<PinholeCamera> pinholeCamera(const KittiCalibration& calibration, int index, int width, int height);

// Parses a calib file ("P0: 12 numbers" ... "R0_rect: 9", "Tr_velo_to_cam: 12"; other keys are
// ignored). Errors name the missing key or the line that does not parse.
Expected<KittiCalibration> parseKittiCalibration(const std::string& text);

struct KittiLabel {
  std::string type;          // Car, Van, Truck, Pedestrian, Person_sitting, Cyclist, Tram, Misc, DontCare
  double truncated = 0.0;    // 0 (in the image) .. 1 (leaving it)
  int occluded = 0;          // 0 visible, 1 partly, 2 largely, 3 unknown
  double alpha = 0.0;        // observation angle
  Box2d box;                 // the annotated 2D box in image 2
  Eigen::Vector3d size_hwl = Eigen::Vector3d::Zero();  // height, width, length (m)
  Eigen::Vector3d location = Eigen::Vector3d::Zero();  // centre of the bottom face, rectified frame (m)
  double rotation_y = 0.0;   // yaw about the camera's y axis (rad)
};

// Parses a label_2 file, one object a line (15 fields). Errors name the line.
Expected<std::vector<KittiLabel>> parseKittiLabels(const std::string& text);

// The 8 corners of a label's box in the rectified camera frame: bottom face first.
std::array<Eigen::Vector3d, 8> boxCorners(const KittiLabel& label);

// A label's box in the Velodyne frame (the LiDAR's): the corners of boxCorners taken back from the
// rectified camera frame (the inverse of R0_rect Tr_velo_to_cam); its centre, its length (along
// yaw, radians about the LiDAR's z from its x), width and height. KITTI's camera y axis is within
// a degree of the LiDAR's -z, so the box is taken as upright.
struct VelodyneBox {
  std::array<Eigen::Vector3d, 8> corners;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double length = 0.0, width = 0.0, height = 0.0, yaw = 0.0;
  bool contains(const Eigen::Vector3d& point) const;
};
VelodyneBox labelBoxInVelodyne(const KittiLabel& label, const KittiCalibration& calibration);

// The pixel of a point (camera frame of `projection`), or nothing when it is not in front (z below
// `near_m`).
std::optional<Eigen::Vector2d> projectPoint(const Eigen::Matrix<double, 3, 4>& projection, const Eigen::Vector3d& point,
                                            double near_m = 0.1);

// The image box around the projected corners, clipped to a width x height image; nothing when a
// corner is behind the camera or the box lies outside the image.
std::optional<Box2d> projectBox(const Eigen::Matrix<double, 3, 4>& projection, const std::array<Eigen::Vector3d, 8>& corners,
                                int width, int height);

}  // namespace fogmap::camera
