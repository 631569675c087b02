#pragma once
// A camera frame with what fogmap knows drawn over it: LiDAR points projected into the image
// (coloured by depth), the 3D boxes of labelled objects projected as wireframes, and 2D detections
// with their labels, and a legend. For a person to check a calibration and a detector by eye.
#include <filesystem>
#include <vector>

#include "common/camera/detection.hpp"
#include "common/camera/kitti.hpp"
#include "common/cloud.hpp"
#include "common/status.hpp"

namespace fogmap::cli {

struct OverlayCounts {
  std::size_t points_drawn = 0;   // LiDAR points that landed in the image
  std::size_t boxes_drawn = 0;    // labelled objects whose box is (partly) in front of the camera
  std::size_t detections_drawn = 0;
};

// Reads `image` (PNG or JPEG, camera 2 of `calibration`), draws the LiDAR points (in the Velodyne
// frame), the labels' 3D boxes and the detections, and writes the PNG `out`. Errors name the file
// that cannot be read or written.
Expected<OverlayCounts> writeCameraOverlay(const std::filesystem::path& image, const camera::KittiCalibration& calibration,
                                           const Cloud& lidar_points, const std::vector<camera::KittiLabel>& labels,
                                           const std::vector<camera::Detection>& detections, const std::filesystem::path& out);

}  // namespace fogmap::cli
