#pragma once
// A simulated camera whose detector is the scene's truth (topology `camera: {source: sim, scene,
// camera, detector: {kind: truth}}`): frame n shows the scene at sim::sceneTime(scene, n, rate_hz),
// the instant a simulated LiDAR shows in its scan n, so cameras and LiDARs of one cluster see the
// same scene at the same unix time. The detections are sim::truthDetections' (seeded misses, box
// jitter); the latency is the runner's to apply. No gRPC, no printing.
#include <cstdint>
#include <string>

#include "common/sim/camera_truth.hpp"
#include "common/sim/scene.hpp"
#include "common/sim/sensor_frames.hpp"
#include "common/base/status.hpp"
#include "common/config/topology.hpp"
#include "common/tracking/track.hpp"

namespace fogmap {

class TruthCamera {
 public:
  // Loads `camera.scene` and finds `camera.camera` in it; errors name the file, or the camera and the
  // scene's cameras, or the truth setting out of range.
  static Expected<TruthCamera> open(const CameraNodeConfig& camera, const std::string& node);
  // The same from a scene in memory; `camera.scene` only names it in errors.
  static Expected<TruthCamera> create(sim::Scene scene, const CameraNodeConfig& camera, const std::string& node);

  // The detections of frame `n`, every one stamped with the node's name and `capture_time_ns`.
  Expected<tracking::DetectionFrame> frame(std::uint64_t n, std::int64_t capture_time_ns);

  double rateHz() const { return rate_hz_; }
  std::int64_t latencyNs() const;
  // Frames in one pass over the scene's duration (ceil(duration_s x rate_hz), at least 1).
  std::uint64_t framesPerPass() const;
  const sim::Scene& scene() const { return scene_; }
  const sim::CameraConfig& camera() const { return scene_.cameras[camera_index_]; }
  std::string describe() const;

 private:
  TruthCamera(sim::Scene scene, std::size_t camera_index, std::string node, double rate_hz,
              sim::TruthReplayConfig replay);

  sim::Scene scene_;
  std::size_t camera_index_ = 0;
  std::string node_;
  double rate_hz_ = 10.0;
  sim::TruthReplayConfig replay_;
  sim::RaycasterCache cache_;  // the scene built once when nothing moves
  bool moving_ = false;
};

}  // namespace fogmap
