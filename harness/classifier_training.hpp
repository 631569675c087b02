#pragma once
// Labelled clusters for the LiDAR-only classifier, from the simulator (`fogctl train-classifier`):
// random scenes of a seed seen by their LiDARs, each frame through the edge's steps (ground
// removal, sensor-aware clustering with the LiDAR's beam table, the L-shape box), each cluster
// labelled by the object most of its points belong to (the simulator's per-point truth).
#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "common/base/status.hpp"
#include "common/camera/kitti.hpp"
#include "common/classify/cluster_views.hpp"
#include "common/classify/object_classifier.hpp"

namespace fogmap::harness {

// The class of a scene object's label: person, car, pole; truck, bus, van: truck_or_bus;
// cyclist, bicycle: cyclist; anything else (crates, pallets, shelves): other.
ObjectClass classOfSceneLabel(std::string_view label);

struct SimSampleOptions {
  int objects = 60;            // per random scene (sim::randomScene)
  int lidars = 4;              // at the paper's spots; the model is the seed's (lidarModelOfSeed)
  double min_majority = 0.8;   // a cluster is labelled when this share of its points is one object's
  std::size_t min_points = 10;
};

// The LiDAR model a seed's scene is seen with: VLP-16, HDL-32E and HDL-64E in turn, so that the
// samples span sparse and dense views.
std::string lidarModelOfSeed(std::uint64_t seed);

struct SampleSet {
  std::vector<LabelledFeatures> samples;
  std::size_t clusters = 0;     // every cluster of at least min_points points
  std::size_t unlabelled = 0;   // clusters without a majority object (ground left over, merged objects)
};

// The samples of the scenes of `seeds`, one frame per LiDAR. The simulator models no reflectance
// (intensity 0), so a forest trained on them alone never splits on intensity. Errors when a scene
// cannot be built or cast.
Expected<SampleSet> simulatedSamples(std::span<const std::uint64_t> seeds, const SimSampleOptions& options = {});

// The class of a KITTI label type: Car; Van, Truck: truck_or_bus; Pedestrian, Person_sitting:
// person; Cyclist; nothing for the others (Tram, Misc, DontCare are not scored).
std::optional<ObjectClass> classOfKittiType(std::string_view type);

// A labelled object of the real KITTI frames, as an edge with boxes sees it (ground removed,
// sensor-aware clustering with the HDL-64E's nominal beam table, eps 0.35 m, 10 points, the
// clusters' views with vehicle parts joined: sensorObjects): the object holding most of the points
// in its label's box.
struct KittiObject {
  std::string frame;
  std::string type;
  ObjectClass truth = ObjectClass::kOther;
  camera::VelodyneBox label_box;            // the label's box, in the velodyne frame
  std::size_t points_in_box = 0;
  double range_m = 0.0;                     // horizontal, from the LiDAR to the box's centre
  std::size_t clusters = 0;                 // objects holding some of the points in its box
  std::optional<ClusterView> found;         // none when most of its points are noise
};

// Every scored label with at least `min_points` points in its box, in the frames of `dir` that
// have all of velodyne/ID.bin, calib/ID.txt and label_2/ID.txt, its objects classed by
// `classifier` (none: no class; vehicle parts then join on their boxes alone). Errors name the file.
Expected<std::vector<KittiObject>> kittiObjects(const std::filesystem::path& dir, const ObjectClassifier* classifier,
                                                std::size_t min_points = 20);

}  // namespace fogmap::harness
