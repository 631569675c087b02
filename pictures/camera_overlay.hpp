#pragma once
// A camera frame with what fogmap knows drawn over it: LiDAR points projected into the image
// (coloured by depth), the 3D boxes of labelled objects projected as wireframes, a map's objects
// (their oriented boxes and classes), 2D detections with their labels, and a legend. For a person to check a calibration and a detector by eye.
#include <filesystem>
#include <span>
#include <vector>

#include "common/base/status.hpp"
#include "common/camera/detection.hpp"
#include "common/camera/kitti.hpp"
#include "common/geometry/cloud.hpp"
#include "common/geometry/map.hpp"

namespace fogmap::pictures {

struct OverlayCounts {
  std::size_t points_drawn = 0;   // LiDAR points that landed in the image
  std::size_t boxes_drawn = 0;    // labelled objects whose box is (partly) in front of the camera
  std::size_t detections_drawn = 0;
  std::size_t objects_drawn = 0;  // map objects with a box or an ellipsoid wholly in front of the camera
  std::size_t object_boxes_drawn = 0;  // of them, drawn as their oriented box (objectBox)
};

// What to draw; views: what they refer to must outlive writeCameraOverlay.
struct OverlayLayers {
  std::span<const Point> lidar_points{};          // Velodyne frame
  std::span<const camera::KittiLabel> labels{};   // their 3D boxes, as wireframes
  std::span<const camera::Detection> detections{};
  // A map of the scan (Velodyne frame, e.g. what an edge makes of it): each object with an oriented
  // box (objectBox) as its 3D wireframe in its class's colour (birdseyeClassColour; a light blue
  // without a class), captioned with the class and confidence; an object without one as the 2D box
  // around its ellipsoids' projections (camera::projectEllipsoid).
  std::span<const MapObject> objects{};
};

// Reads `image` (PNG or JPEG, camera 2 of `calibration`), draws the layers and writes the PNG
// `out`. Errors name the file that cannot be read or written.
Expected<OverlayCounts> writeCameraOverlay(const std::filesystem::path& image, const camera::KittiCalibration& calibration,
                                           const OverlayLayers& layers, const std::filesystem::path& out);

}  // namespace fogmap::pictures
