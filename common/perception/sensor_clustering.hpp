#pragma once
// Sensor-aware Euclidean clustering, in the manner of range-image methods (Bogoslavskyi and
// Stachniss 2016; Zermas et al. 2017): the exact Euclidean links of euclideanClusters, plus
// vertical links between adjacent rings of the LiDAR. With eps 0.35 m a VLP-16 (2 degrees between
// rings) puts its rings 0.5 to 0.9 m apart at 15 to 25 m, so a person is several ring slices
// for the exact mode; the ring links make it one object again.
//
// The linking rule (the specification; BeamGeometry::index gives ring, azimuth bin and range):
// points p and q are connected when
//   (a) |p - q| < eps, strictly and exactly as euclideanClusters decides it (in float, as PCL), or
//   (b) both have a beam, their rings are adjacent in ascending elevation (|ring_p - ring_q| == 1),
//       their azimuth bins differ by at most azimuth_window (cyclically, over azimuthBins()),
//       |range_p - range_q| < eps (depth continuity: an object seen behind another stays apart),
//       and, with reach = (ring_gap_slack * gap_rad) * min(range_p, range_q), where gap_rad is
//       elevationRad(upper ring) - elevationRad(lower ring): reach > eps and |p - q| < reach.
//       Rule (b) is evaluated in double: the coordinates of p and q as given (the points' frame),
//       |p - q|^2 as (dx^2 + dy^2) + dz^2 against reach^2.
// Where the ring gap at that range is no wider than eps (reach <= eps), the rings are closer than
// eps and rule (a) already joins what they see: rule (b) adds nothing there, so the range image
// holds only the points far enough from the sensor for a ring link to reach past eps (beyond
// eps / (slack x the wider of the ring's two gaps); for an HDL-64E at eps 0.35 m, 27 to 40 m).
// Clusters are the connected components; components with fewer than min_points or more than
// max_points points are noise (-1); labels are canonical (as canonicalize). Non-finite points
// connect to nothing and are noise, as in euclideanClusters. A point at the sensor's origin
// (range 0) has no beam and is linked by rule (a) only; rule (b) could give it nothing more (its
// bound would be eps).
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Geometry>

#include "common/base/status.hpp"
#include "common/geometry/cloud.hpp"
#include "common/perception/clustering.hpp"
#include "common/perception/lidar_models.hpp"

namespace fogmap {

// The sensor's geometry as clustering needs it.
struct BeamTable {
  std::vector<double> elevations_deg;  // one per ring, any order; up is positive, within [-90, 90]
  double azimuth_step_deg = 0.2;       // horizontal angle between consecutive rays of a ring
};

// A LiDAR model's beam table: its rings' elevations and one revolution's azimuth steps.
BeamTable beamTableOf(const LidarModel& model);

// What the sensor-aware mode adds to the exact links: the sensor's geometry and the reach of the
// ring links (rule b).
struct SensorLinks {
  BeamTable beams;
  Eigen::Isometry3d sensor_pose = Eigen::Isometry3d::Identity();  // sensor frame -> the points' frame
  double ring_gap_slack = 1.5;  // a vertical link may span slack x the ring gap at that range
  int azimuth_window = 2;       // azimuth bins either side searched on the adjacent ring
};

struct SensorClusteringParams {
  ClusteringParams clustering;  // eps_m, min_points, max_points; threads for the Euclidean links (a)
  SensorLinks links;
};

// Errors (invalid argument, naming the field) for: eps_m not positive and finite; fewer than 2
// elevations, one not finite or outside [-90, 90] degrees, two equal; an azimuth step not positive
// and finite, or so small that the range image would exceed 2^24 bins per ring or 2^32 cells; a
// slack below 1 or not finite; a negative window; a sensor pose that is not finite and rigid.
Status validateSensorClusteringParams(const SensorClusteringParams& params);

// Where a point falls in the sensor's range image.
struct BeamIndex {
  static constexpr int kNoBeam = -1;
  int ring = kNoBeam;    // index into the elevations sorted ascending; kNoBeam: non-finite or range 0
  int azimuth_bin = -1;  // in [0, azimuthBins())
  double range_m = 0.0;  // distance from the sensor's origin
};

// A validated beam table and sensor pose, prepared to index points.
class BeamGeometry {
 public:
  static Expected<BeamGeometry> make(const SensorClusteringParams& params);

  // The point in the sensor frame (sensor_pose.inverse() applied, in double): range = its norm;
  // ring = the elevation nearest to asin(z / range), decided in sine space against the sines of
  // the midpoints between consecutive sorted elevations (a point exactly on one goes to the lower
  // ring); azimuth bin = floor((atan2(y, x) + pi) / step_rad), where the closing angle pi (the
  // same direction as -pi) and any rounding past the last bin wrap to bin 0. Rays fired at
  // k x step from +x (as the simulator fires them) lie on bin edges: rounding puts each on one
  // side, so one ray may fall one bin apart on two rings; an azimuth_window of 1 or more absorbs it.
  BeamIndex index(const Point& point) const;

  int rings() const { return static_cast<int>(elevations_rad_.size()); }
  // ceil(360 / azimuth_step_deg), taking a quotient within 1e-9 of a whole number as that number.
  int azimuthBins() const { return bins_; }
  // Elevation of `ring` (sorted ascending), radians.
  double elevationRad(int ring) const { return elevations_rad_[static_cast<std::size_t>(ring)]; }

 private:
  friend class SensorClusterer;
  BeamGeometry() = default;
  // The steps of index(), which the clustering takes for blocks of points: the same functions,
  // the same numbers.
  struct SensorPoint {
    double x, y, z, range;
  };
  Eigen::Vector3d toSensorFrame(const Point& point) const { return to_sensor_ * Eigen::Vector3d(point.x, point.y, point.z); }
  static SensorPoint withRange(const Eigen::Vector3d& s) { return {s.x(), s.y(), s.z(), std::sqrt(s.squaredNorm())}; }
  SensorPoint toSensor(const Point& point) const { return withRange(toSensorFrame(point)); }
  int ringOfSine(double sine) const;  // sine = z / range
  // (angle + pi) / step_rad from a fast atan2 (NaN where x = y = 0).
  double fastBinCoordinate(double x, double y) const;
  // The bin of that coordinate where no bin edge is near it; next to an edge, the side of the
  // edge the point is on; where it is all but on the edge, the formula with std::atan2.
  int azimuthBin(double fast_coordinate, double x, double y) const;
  int exactAzimuthBin(double x, double y) const;

  std::vector<double> elevations_rad_;    // ascending
  std::vector<double> sin_midpoints_;     // sin((e_k + e_k+1) / 2), ascending, then +infinity
  std::vector<std::int32_t> ring_below_;  // per cell of sine space: rings certainly below its sines
  Eigen::Isometry3d to_sensor_ = Eigen::Isometry3d::Identity();
  double step_rad_ = 0.0;
  double bins_per_rad_ = 0.0;   // 1 / step_rad_
  double fast_margin_ = 0.0;    // bins: how far the fast atan2 may be off, rounding included
  double closing_bin_ = 0.0;    // 2 pi / step_rad_: where the angle pi (the closing one) falls
  std::vector<double> edge_cos_, edge_sin_;  // direction of each bin's lower edge (up to 2^16 bins)
  int bins_ = 1;
};

// Sensor-aware clustering with its parameters checked and its beam geometry and ring links
// prepared once (an edge's start-up: about 15 us for a VLP-16, a tenth of clustering one of its
// object scans), for frame after frame.
class SensorClusterer {
 public:
  // Errors when validateSensorClusteringParams refuses the parameters.
  static Expected<SensorClusterer> create(const SensorClusteringParams& params);
  // Sensor-aware clusters by the rule above: the exact links of euclideanClusters (run with the
  // given threads), then the vertical links of a range image sorted by (ring, azimuth bin) on one
  // thread. Errors only for more than 2^32 - 1 points.
  Expected<Clustering> cluster(std::span<const Point> points) const;
  const SensorClusteringParams& params() const { return params_; }

 private:
  SensorClusterer(SensorClusteringParams params, BeamGeometry geometry);
  SensorClusteringParams params_;
  BeamGeometry geometry_;
  std::vector<double> gap_link_;   // per pair of adjacent rings: slack x their elevation gap
  std::vector<double> ring_link_;  // per ring: the wider link of its two gaps
  double near_squared_ = 0.0;      // squared range within which no ring's link reaches past eps
};

// SensorClusterer::create(params), then cluster(points): for one cloud.
Expected<Clustering> sensorAwareClusters(std::span<const Point> points, const SensorClusteringParams& params);

}  // namespace fogmap
