#pragma once
// Minimal "--flag value" parsing for fogctl's commands (unknown flags are errors), and what the
// flags several commands share mean: the state directory of up and down, the root connection of
// watch and geofence, the clustering flags of cluster and bench.
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "common/base/status.hpp"
#include "common/config/topology.hpp"
#include "common/geometry/cloud.hpp"
#include "common/perception/clustering.hpp"
#include "common/sim/scene_topology.hpp"

namespace grpc {
class ChannelCredentials;
}  // namespace grpc

namespace fogmap {
class ObjectClassifier;
}
namespace fogmap::view {
class ViewRuntime;
}

namespace fogmap::cli {

class Args {
 public:
  // Parses argv[first..argc) as "--name value" pairs and bare "--switch" flags (listed in `switches`).
  static Expected<Args> parse(int argc, char** argv, int first, const std::set<std::string>& valued,
                              const std::set<std::string>& switches);

  bool has(const std::string& name) const { return values_.count(name) > 0; }
  std::string get(const std::string& name, const std::string& fallback = "") const;
  Expected<double> getDouble(const std::string& name, double fallback) const;
  Expected<long> getInt(const std::string& name, long fallback) const;
  const std::vector<std::string>& positional() const { return positional_; }

 private:
  std::map<std::string, std::string> values_;
  std::vector<std::string> positional_;
};

// Prints "WHO: message" on stderr and returns the exit code: 2 for invalid arguments, else 1.
int fail(const Error& error, const std::string& who = "fogctl");

// State directories are absolute, so that up and down find the same one from any working
// directory: --state is taken relative to where fogctl runs, the default (.fogmap/NAME) relative
// to the topology file.
Expected<std::filesystem::path> absoluteDir(const std::filesystem::path& dir);
Expected<std::filesystem::path> stateDir(const Args& args, const std::filesystem::path& topology_file, const TopologyConfig& t);

// The client identity flags of the commands that talk to the root, for their usage text.
inline constexpr const char* kTlsFlagsUsage =
    "With TLS (the topology's tls section) fogctl presents a client certificate:\n"
    "  --identity NAME  NAME.crt and NAME.key in the topology's tls.cert_dir (default: operator)\n"
    "  --cert FILE --key FILE --ca FILE   explicit files instead (with --target, no topology needed)\n";

// How fogctl reaches the root aggregator (or a tracker): its address and the transport credentials.
struct RootConnection {
  std::string target;
  std::shared_ptr<grpc::ChannelCredentials> credentials;
};

// The root's address: --target HOST:PORT, or the root (`server` kTracker: the first tracker) of
// the topology file given. The credentials: --cert, --key and --ca when given; else, when the
// topology has a tls section, the certificate of --identity NAME (default: operator) in its
// cert_dir; else plaintext. Every file is read and checked here, so a problem is reported before
// any connection is tried. `usage` is the error without a topology or a target.
Expected<RootConnection> rootConnection(const Args& args, const std::string& usage, Role server = Role::kAggregator);

// --eps, --min-points and --threads, validated.
Expected<ClusteringParams> clusteringParams(const Args& args);

// The committed LiDAR classifier (fogctl train-classifier), from the project's folder.
inline constexpr const char* kDefaultClassifierModel = "data/models/lidar_classifier.yml.gz";
// Where the committed classifier is: beside the build that holds this fogctl (its bin/../..), else
// under the working directory; none when neither has it.
std::optional<std::filesystem::path> bundledClassifierModel();

// The classifier of --classifier FILE (an error naming the file when it does not load), else the
// bundled model when it is there, else none (nullptr): objects then get boxes without classes.
Expected<std::shared_ptr<const ObjectClassifier>> classifierFlag(const Args& args);

// --clustering exact|sensor, --fragment-min-points N|off (N from 1 to 1000), --alpha-max A|off and --objects
// none|boxes|classes with --classifier FILE (default the bundled model): how a scene's edges make
// their maps (demo, topology --scene), over `defaults` (their objects too, when --objects is not given).
Expected<sim::SceneMapping> sceneMapping(const Args& args, const sim::SceneMapping& defaults);
inline constexpr const char* kSceneMappingUsage =
    "  --clustering exact|sensor   how the edges cluster: exact (PCL's Euclidean partition) or sensor (with\n"
    "                 ring links from each LiDAR model's beam table, so that a sparse LiDAR's rings join;\n"
    "                 the default for a scene)\n"
    "  --fragment-min-points N|off edges ship their clusters of at least N points (default for a scene: 1)\n"
    "                 as fragments, and min_points applies to a global object's points over all its\n"
    "                 sensors, at the root; off: an edge drops its clusters below min_points (the paper's\n"
    "                 MAD-C, the default for recorded scans)\n"
    "  --alpha-max A|off           each ellipsoid reaches its cluster's farthest point along each of its\n"
    "                 axes, from alpha up to A standard deviations (madc.alpha_max; default for a scene:\n"
    "                 2.5); off: alpha for every ellipsoid (the paper's, the default for recorded scans)\n"
    "  --objects none|boxes|classes  what the edges say of each cluster of min_points beyond its\n"
    "                 ellipsoid: nothing, its oriented box (L-shape fit, up to 16 bytes more an ellipsoid on\n"
    "                 the wire), or its box and LiDAR class (topology section objects:); default classes for\n"
    "                 demo --scene (boxes where the bundled model is not found), none otherwise\n"
    "  --classifier FILE           with classes: the model (default data/models/lidar_classifier.yml.gz)\n";

// Reads --input within --max-scan-bytes (--remove-ground: the points above the ground); non-finite
// points are kept in place (they cluster as noise) when `keep_non_finite`, so that the cloud lines
// up with the file point for point. Says on stderr how many non-finite points it met.
Expected<Cloud> loadScan(const Args& args, bool keep_non_finite);

// The live view of `topology` (fogctl view, and fogctl up --view) on --listen (default 127.0.0.1)
// and `port`: the root's global map and, where the topology has one, its tracker's tracks, over the
// connection rootConnection gives (--identity and the others); --geofences and --max-pages read.
Expected<std::unique_ptr<view::ViewRuntime>> startLiveView(const Args& args, const TopologyConfig& topology, std::uint16_t port);

}  // namespace fogmap::cli
