#pragma once
// What `fogctl view` shows, as the JSON events its page draws (view/web/view.js reads them): the
// topology's sensors and geofences (config), each global map (map), each set of tracks (tracks)
// and the state of the links to the root and the tracker (status). Pure: domain types in, text out;
// the feed (view_feed.hpp) and the web server (web_server.hpp) move it.
//
// Coordinates are metres in the common frame; angles are degrees, counter-clockwise from +x;
// times are milliseconds of Unix time (a double holds them to the microsecond, where nanoseconds
// would not survive JavaScript's numbers).
#include <cstddef>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/base/status.hpp"
#include "common/config/topology.hpp"
#include "common/geometry/ellipsoid.hpp"
#include "common/io/messages.hpp"
#include "common/tracking/track_snapshot.hpp"

namespace fogmap::view {

// A geofence the page draws: an axis-aligned box (as `fogctl geofence set --box` makes one).
struct FenceBox {
  std::string name;
  Eigen::Vector3d min = Eigen::Vector3d::Zero();
  Eigen::Vector3d max = Eigen::Vector3d::Zero();
};

// "NAME=XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX[;NAME=...]": an error naming the part that is wrong (a
// missing name, not six finite numbers, a minimum not below its maximum, a name given twice).
Expected<std::vector<FenceBox>> parseFenceBoxes(const std::string& text);

struct SensorMark {
  std::string name;  // the node's
  std::string kind;  // "lidar" or "camera"
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  double heading_deg = 0.0;  // where the sensor's forward axis points, seen from above
};

struct NodeMark {
  std::uint32_t id = 0;
  std::string name;
  std::string role;  // roleName
};

struct ViewConfig {
  std::string topology;
  std::vector<SensorMark> sensors;
  std::vector<FenceBox> geofences;
  std::vector<NodeMark> nodes;
  bool has_tracker = false;
};

// The sensors of the topology's edges (the LiDAR's pose: its x axis forward) and detection nodes
// (the camera's calibration: its z axis forward), its nodes, and `geofences`.
ViewConfig viewConfigOf(const TopologyConfig& topology, std::vector<FenceBox> geofences);

// An ellipsoid seen from above: the ellipse its points cover on the ground plane (the top-left
// 2 x 2 block of its shape matrix), with semi-axes a >= b and the angle of a's axis.
struct GroundEllipse {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  double a = 0.0;
  double b = 0.0;
  double angle_rad = 0.0;  // in (-pi/2, pi/2]
};
GroundEllipse groundEllipse(const Ellipsoid& ellipsoid);

// One link of the view (to the root, or to the tracker).
struct LinkState {
  bool connected = false;
  std::string target;  // host:port
  std::string detail;  // why it is not connected (empty when it is)
};

// The view's state between events: the last epoch each node contributed to, each track's trail.
// Not thread-safe: the caller serialises (ViewRuntime does).
class LiveView {
 public:
  // Each track keeps its last `trail_points` positions (at least 1); at most `max_trails` tracks
  // keep one (those beyond are drawn without it), so a flood of track ids costs bounded memory.
  explicit LiveView(ViewConfig config, std::size_t trail_points = 50, std::size_t max_trails = 4096);

  const ViewConfig& config() const { return config_; }
  std::string configEvent() const;
  // The objects (ground ellipses per view, oriented box and class where the edges give them),
  // which geofences they occupy (geofence.hpp's classify, as the root answers queries), and each
  // node: missing from this epoch or not, and the last epoch it contributed to.
  std::string mapEvent(const GlobalMapMessage& global);
  // The tracks with their trails; a track not in `snapshot` loses its trail.
  std::string tracksEvent(const tracking::TrackSnapshot& snapshot);
  std::string statusEvent(const LinkState& root, const std::optional<LinkState>& tracker, std::uint64_t skipped_events,
                          std::int64_t now_ns) const;

 private:
  std::string nodeName(std::uint32_t id) const;

  ViewConfig config_;
  std::size_t trail_points_;
  std::size_t max_trails_;
  std::map<std::uint32_t, std::string> node_names_;
  std::map<std::uint32_t, std::uint64_t> last_epoch_;  // per node that has contributed
  std::map<std::uint64_t, std::deque<Eigen::Vector2d>> trails_;
};

}  // namespace fogmap::view
