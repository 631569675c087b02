#include "services/detection/truth_camera.hpp"
#include "common/config/camera_node.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <utility>

namespace fogmap {

TruthCamera::TruthCamera(sim::Scene scene, std::size_t camera_index, std::string node, double rate_hz,
                         sim::TruthReplayConfig replay)
    : scene_(std::move(scene)),
      camera_index_(camera_index),
      node_(std::move(node)),
      rate_hz_(rate_hz),
      replay_(replay),
      moving_(sim::anythingMoves(scene_)) {}

Expected<TruthCamera> TruthCamera::open(const CameraNodeConfig& camera, const std::string& node) {
  Expected<sim::Scene> scene = sim::loadScene(camera.scene);
  if (!scene) return scene.error();
  return create(std::move(*scene), camera, node);
}

Expected<TruthCamera> TruthCamera::create(sim::Scene scene, const CameraNodeConfig& camera, const std::string& node) {
  if (!(camera.rate_hz > 0.0) || !std::isfinite(camera.rate_hz)) {
    return invalidArgument("camera '" + node + "': rate_hz must be positive and finite");
  }
  const auto found = std::find_if(scene.cameras.begin(), scene.cameras.end(),
                                  [&](const sim::CameraConfig& c) { return c.name == camera.camera; });
  if (found == scene.cameras.end()) {
    std::string known;
    for (const sim::CameraConfig& c : scene.cameras) known += (known.empty() ? "'" : ", '") + c.name + "'";
    return invalidArgument(camera.scene.string() + ": the scene has no camera '" + camera.camera +
                           "' (its cameras: " + (known.empty() ? "none" : known) + ")");
  }
  // The scene's seed, so that a scene file alone fixes what its cameras report.
  const sim::TruthReplayConfig replay{camera.truth_replay.miss_rate, camera.truth_replay.box_jitter_px,
                                      camera.truth_replay.latency_ms, scene.seed};
  if (const Status s = sim::validate(replay); !s) return invalidArgument("truth." + s.error().message);
  const auto index = static_cast<std::size_t>(found - scene.cameras.begin());
  return TruthCamera(std::move(scene), index, node, camera.rate_hz, replay);
}

Expected<tracking::DetectionFrame> TruthCamera::frame(std::uint64_t n, std::int64_t capture_time_ns) {
  const double time_s = sim::sceneTime(scene_, n, rate_hz_);
  std::optional<sim::SceneRaycaster> built;
  const sim::SceneRaycaster* raycaster = nullptr;
  if (!moving_ && cache_.still) {
    raycaster = &*cache_.still;
  } else {
    Expected<sim::SceneRaycaster> b = sim::SceneRaycaster::build(scene_, time_s);
    if (!b) return b.error();
    if (moving_) {
      built.emplace(std::move(*b));
      raycaster = &*built;
    } else {
      cache_.still.emplace(std::move(*b));
      raycaster = &*cache_.still;
    }
  }
  // Draws by the frame's place in the scene's cycle, as the LiDARs' noise: a cycle replays exactly.
  Expected<sim::TruthDetectionFrame> truth =
      sim::truthDetections(scene_, *raycaster, camera(), sim::cycleFrame(scene_, n, rate_hz_), replay_);
  if (!truth) return truth.error();
  tracking::DetectionFrame out;
  out.camera = node_;
  out.capture_time_ns = capture_time_ns;
  out.detections = std::move(truth->detections);
  for (camera::Detection& d : out.detections) {
    d.camera = node_;
    d.capture_time_ns = capture_time_ns;
  }
  return out;
}

std::int64_t TruthCamera::latencyNs() const { return std::llround(replay_.latency_ms * 1e6); }

std::uint64_t TruthCamera::framesPerPass() const {
  const double frames = scene_.duration_s * rate_hz_;
  const double whole = std::round(frames);
  if (std::abs(frames - whole) <= 1e-9 * whole) return std::max<std::uint64_t>(1, static_cast<std::uint64_t>(whole));
  return std::max<std::uint64_t>(1, static_cast<std::uint64_t>(std::ceil(frames)));
}

std::string TruthCamera::describe() const {
  std::ostringstream out;
  out << "truth of simulated camera '" << camera().name << "' in scene " << scene_.name << " (" << scene_.objects.size()
      << " objects, " << (moving_ ? "moving" : "static") << ") at " << rate_hz_ << " Hz, miss rate "
      << replay_.miss_rate << ", box jitter " << replay_.box_jitter_px << " px, latency " << replay_.latency_ms << " ms";
  return out.str();
}

}  // namespace fogmap
