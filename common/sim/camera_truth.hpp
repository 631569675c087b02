#pragma once
// What a perfect 2D detector would report for a simulated camera (truth replay): the image box of
// every object the camera sees at one instant, labelled with the object's label, optionally made
// imperfect by seeded misses, box jitter and a delivery latency. Lets the fusion tracker be run and
// scored on simulated scenes without an image renderer or a learned detector. Pure.
#include <cstdint>
#include <string>
#include <vector>

#include "common/base/status.hpp"
#include "common/camera/detection.hpp"
#include "common/camera/pinhole.hpp"
#include "common/sim/raycaster.hpp"
#include "common/sim/scene.hpp"

namespace fogmap::sim {

// The common camera model of a scene camera: same intrinsics and image, no distortion, extrinsics
// world_to_camera = pose^-1 (scene cameras are camera -> scene).
camera::PinholeCamera pinholeOf(const CameraConfig& camera);

// How far truth replay falls short of a perfect detector. Every draw comes from a counter-based hash
// of (seed, camera name, frame, object id), so a detection does not depend on which cameras, frames
// or objects were asked for before it; a higher miss rate misses a superset of a lower one's misses.
struct TruthReplayConfig {
  double miss_rate = 0.0;      // probability in [0, 1] that a visible object gives no detection
  double box_jitter_px = 0.0;  // Gaussian sigma added to each of a box's four edges, pixels
  double latency_ms = 0.0;     // from capture to the detections' arrival (the detector's time)
  std::uint64_t seed = 1;
};

// Ok, or an invalid-argument error naming the first field out of range.
Status validate(const TruthReplayConfig& config);

// One camera image's detections, with the truth behind them.
struct TruthDetectionFrame {
  std::string camera;
  std::int64_t capture_time_ns = 0;  // the scene instant, in ns of scene time
  std::int64_t arrival_time_ns = 0;  // capture_time_ns + latency
  std::vector<camera::Detection> detections;  // in the scene's object order
  std::vector<std::uint32_t> objects;         // the object of each detection
};

// The detections of `camera` at the instant `raycaster` was built for (it must be built from
// `scene`): every object with a sample point (its parts' centres, the centres of their faces)
// that a ray from the camera's centre reaches on that object first, and whose projected bounds
// (box corners; points around a cylinder's rims) lie in front of the camera and overlap the image,
// boxed by those bounds plus jitter and clipped to the image; minus the seeded misses. `frame`
// numbers the image for the draws. An error for an invalid config or camera.
Expected<TruthDetectionFrame> truthDetections(const Scene& scene, const SceneRaycaster& raycaster,
                                              const CameraConfig& camera, std::uint64_t frame,
                                              const TruthReplayConfig& config);

}  // namespace fogmap::sim
