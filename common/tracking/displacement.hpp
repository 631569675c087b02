#pragma once
// Displacement centroids (the camera-LiDAR fusion paper's Algorithm 1): the points of a frame that
// fall in voxels the previous frame left empty, clustered with DBSCAN; clusters flat in z (ground
// revealed by a moving object) are dropped, the others become centroids. Frames are compared in the
// sensor frame, so the sensor is assumed to stand still (as in the paper). Pure; one detector per
// sensor, fed its frames in order.
#include <cstddef>
#include <memory>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "common/base/status.hpp"
#include "common/geometry/cloud.hpp"
#include "common/tracking/displacement_config.hpp"
#include "common/tracking/track.hpp"

namespace fogmap::tracking {

struct DisplacementResult {
  std::vector<DisplacementCentroid> centroids;  // kept clusters, in the order of their first point in the frame
  std::size_t displacement_points = 0;          // finite points in voxels empty in the previous frame
  std::size_t clusters = 0;                     // DBSCAN clusters, before the z filter
  std::size_t dropped_flat = 0;                 // clusters dropped by the z-variance filter
  std::size_t non_finite = 0;                   // points with a NaN or infinite coordinate, skipped
  std::size_t beyond_reach = 0;                 // finite points farther than reachM() on some axis, skipped
};

class DisplacementDetector {
 public:
  // A detector with no previous frame, or the validation error of `params`.
  static Expected<DisplacementDetector> create(const DisplacementParams& params);

  DisplacementDetector(DisplacementDetector&&) noexcept;
  DisplacementDetector& operator=(DisplacementDetector&&) noexcept;
  ~DisplacementDetector();

  // Displacement centroids of `frame` against the previous frame pushed (the whole frame is
  // displacement on the first push), then keeps `frame` as the previous frame.
  DisplacementResult push(std::span<const Point> frame);

  const DisplacementParams& params() const { return params_; }
  // How far from the sensor, on each axis, points are taken: 2^19 voxels (52 km with 0.1 m voxels).
  // Points farther away are skipped and counted in beyond_reach.
  double reachM() const;

 private:
  struct ChangeDetector;  // PCL's double-buffered octree: the previous frame's voxels and the current one's

  explicit DisplacementDetector(const DisplacementParams& params);

  DisplacementParams params_;
  std::unique_ptr<ChangeDetector> change_;
};

}  // namespace fogmap::tracking
