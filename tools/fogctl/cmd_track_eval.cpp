// fogctl track-eval: the fusion tracker on a simulated moving scene, scored against its truth
// (harness/tracking_eval.hpp).
#include <cstdio>
#include <fstream>
#include <string>

#include "harness/tracking_eval.hpp"
#include "tools/fogctl/args.hpp"
#include "tools/fogctl/commands.hpp"

namespace fogmap::cli {
namespace {

using harness::TrackingEvalConfig;
using harness::runTrackingEval;
using harness::trackingJson;
using harness::trackingTableMarkdown;

int runTrackEval(int argc, char** argv) {
  const std::string who = "fogctl track-eval";
  const auto args = Args::parse(argc, argv, 2, {"people", "vehicles", "lidars", "cameras", "frames", "seed", "visible-side-radius", "merge-radius", "json"}, {});
  if (!args) return fail(args.error(), who);
  TrackingEvalConfig config;
  const auto count = [&](const std::string& flag, int fallback) -> Expected<int> {
    const auto v = args->getInt(flag, fallback);
    if (!v) return v.error();
    if (*v < 0 || *v > 100000) return invalidArgument("--" + flag + " must be a count from 0 to 100000");
    return static_cast<int>(*v);
  };
  for (auto [flag, field] : {std::pair{"people", &config.people}, std::pair{"vehicles", &config.vehicles},
                             std::pair{"lidars", &config.lidars}, std::pair{"cameras", &config.cameras},
                             std::pair{"frames", &config.frames}}) {
    const auto v = count(flag, *field);
    if (!v) return fail(v.error(), who);
    *field = *v;
  }
  const auto seed = args->getInt("seed", static_cast<long>(config.seed));
  if (!seed || *seed < 0) return fail(invalidArgument("--seed must be a non-negative integer"), who);
  config.seed = static_cast<std::uint64_t>(*seed);
  const auto radius = args->getDouble("visible-side-radius", config.visible_side_max_radius_m);
  if (!radius || !(*radius >= 0.0 && *radius <= 10.0)) {
    return fail(invalidArgument("--visible-side-radius must be a radius in metres from 0 to 10"), who);
  }
  config.visible_side_max_radius_m = *radius;
  const auto merge = args->getDouble("merge-radius", config.merge_radius_m);
  if (!merge || !(*merge >= 0.0 && *merge <= 10.0)) {
    return fail(invalidArgument("--merge-radius must be a distance in metres from 0 to 10"), who);
  }
  config.merge_radius_m = *merge;

  auto result = runTrackingEval(config);
  if (!result) return fail(result.error(), "fogctl");  // its errors say "track-eval: ..." already
  std::fputs(trackingTableMarkdown(*result).c_str(), stdout);
  std::printf("\n%s", who.c_str());
  for (int i = 2; i < argc; ++i) std::printf(" %s", argv[i]);
  std::printf(": %.1f s\n", result->seconds);
  if (args->has("json")) {
    const std::string path = args->get("json");
    std::ofstream out(path);
    out << trackingJson(*result);
    if (!out) return fail(ioError("cannot write " + path), who);
  }
  return 0;
}

}  // namespace

Command trackEvalCommand() {
  return {"track-eval",
          "[--people 6] [--vehicles 2] [--lidars 4] [--cameras 4] [--frames 200] [--seed 1] [--json FILE]   the fusion tracker",
          "usage: fogctl track-eval [--people 6] [--vehicles 2] [--lidars 4] [--cameras 4] [--frames 200] [--seed 1]\n"
          "                         [--visible-side-radius 0.4] [--merge-radius 1.0] [--json FILE]\n"
          "Runs the fusion tracker on a simulated moving scene (fogctl scene moving) through the real chain:\n"
          "each LiDAR's 10 Hz frames through its displacement detector, the centroids of one instant merged\n"
          "into one LiDAR frame, every camera's detections replayed from the truth (seeded misses, 2 px box\n"
          "jitter, 50 ms latency). The paper and kalman associations run for 0, 30 and 60 % missed detections\n"
          "on the same frames; prints MOTA, MOTP, ID switches, fragmentations, IDF1, localization error (also\n"
          "for people within 15 m of a LiDAR), tracks confirmed and the tracker's time per LiDAR frame.\n"
          "  --people N, --vehicles M   walking people and driving cars on crossing paths across 40 x 40 m\n"
          "  --lidars K   VLP-16s at the MAD-C paper's spots, 1 to 7; --cameras C   around the area, 0 to 6\n"
          "  --frames N   scored LiDAR frames (default 200: 20 s)\n"
          "  --visible-side-radius R   centroids narrower than R m are placed on the object's axis, not on the\n"
          "               side their LiDAR sees (0: as Algorithm 1 gives them; default 0.4)\n"
          "  --merge-radius M   centroids of one instant closer than M m are one observation (default 1.0)\n"
          "  --json FILE  every figure as JSON\n",
          runTrackEval};
}

}  // namespace fogmap::cli
