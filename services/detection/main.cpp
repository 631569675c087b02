// detection: one camera's 2D detector. Reads the camera's frames, detects objects in them and
// streams every frame's detections to the node's tracker (TrackerService.PushDetections).
// Composition root only: the process's parts and how it ends are DetectionProcess's, the loops
// DetectionRunner's, the stream DetectionLink's.
//
// A detection node in a topology file (its parent is a tracker):
//
//   - name: cam-front
//     id: 20
//     role: detection
//     parent: tracker
//     host: 127.0.0.1
//     metrics_port: 9120
//     camera:
//       source: data/kitti_raw_seq_a/image_02   # images, a video file, /dev/video0, or sim
//       rate_hz: 10
//       loop: true
//       queue_frames: 2
//       max_image_pixels: 16777216                # default 4096 x 4096; larger frames are refused undecoded
//       detector: {kind: hog, hog: {upscale: 1.5}}
//       calibration: {fx: 721.5, fy: 721.5, cx: 609.6, cy: 172.9, width: 1242, height: 375,
//                     pose: {translation_m: [0, 0, 1.65], rpy_deg: [-90, 0, -90]}}
//
// A simulated camera replays the scene's truth instead of running a detector:
//       source: sim
//       scene: data/scenes/example.yaml
//       camera: camera-1
//       detector: {kind: truth, truth: {miss_rate: 0.1, box_jitter_px: 2, latency_ms: 40}}
#include <cstdlib>

#include "services/common/service_main.hpp"
#include "services/detection/detection_process.hpp"

int main(int argc, char** argv) {
  const fogmap::ServiceSpec spec{fogmap::Role::kDetection, "usage: detection --topology FILE --node NAME\n"};
  return fogmap::runService(argc, argv, spec, [](fogmap::ServiceContext& context) {
    auto process = fogmap::DetectionProcess::create(context);
    if (!process) return context.badConfig(process.error().message);
    context.serveMetrics();
    const int code = (*process)->run();
    // Not destroyed: its loops' threads would be joined, and a detection at work would hold the
    // exit for as long as it takes.
    if ((*process)->unfinished()) std::_Exit(code);
    return code;
  });
}
