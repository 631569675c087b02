#pragma once
// A detection node's section of the topology (`camera:`): its frames, calibration and detector.
// NodeConfig::camera holds one; include this header to look inside it.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

#include "common/camera/detector_config.hpp"
#include "common/camera/image_limits.hpp"
#include "common/camera/pinhole.hpp"
#include "common/config/topology.hpp"

namespace fogmap {

// What a detection node replays as its detector's output instead of running one (`detector: {kind:
// truth}`): the simulated scene's objects projected into the camera (source sim), with seeded
// misses, box jitter and latency, for repeatable tests and evaluations.
struct TruthReplayConfig {
  double miss_rate = 0.0;     // probability that a visible object is not reported
  double box_jitter_px = 0.0;  // Gaussian sigma added to each box edge
  double latency_ms = 0.0;     // how long after the capture the detections are sent
};

// A detection node's camera (`camera:`): where its frames come from, its calibration and its
// detector.
struct CameraNodeConfig {
  // A directory of images (replayed in name order), a video file, a V4L2 device (/dev/videoN), or
  // sim: camera `camera` of the scene `scene`, whose objects are projected (detector truth).
  std::filesystem::path source;
  std::filesystem::path scene;
  std::string camera;
  double rate_hz = 10.0;                // replay rate of a directory (and sim); devices and videos keep theirs
  bool loop = true;
  std::optional<std::uint64_t> frames;  // stop after this many frames
  std::size_t queue_frames = 2;         // frames waiting for a slower detector; beyond, the oldest is dropped
  // Frames with more pixels are refused from their header, before decoding (common/camera/image_limits.hpp).
  std::uint64_t max_image_pixels = camera::kDefaultMaxImagePixels;
  bool truth = false;                   // detector kind truth: replay the scene's objects (source sim only)
  camera::DetectorConfig detector;      // kind hog, cascade or dnn (paths resolved against the topology)
  TruthReplayConfig truth_replay;
  // The camera's calibration in the common frame (`calibration:` {fx, fy, cx, cy, width, height,
  // distortion: [k1, k2, p1, p2, k3], pose: camera -> common frame, x right, y down, z forward}).
  camera::PinholeCamera calibration;

  bool simulated() const { return source == kSimSource; }
};

}  // namespace fogmap
