// fogctl split: cuts a scan into overlapping sectors, one virtual LiDAR each.
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "common/io/cloud_io.hpp"
#include "common/base/angles.hpp"
#include "common/perception/virtual_lidar.hpp"
#include "tools/fogctl/args.hpp"
#include "tools/fogctl/commands.hpp"

namespace fogmap::cli {
namespace {

int runSplit(int argc, char** argv) {
  const auto args = Args::parse(argc, argv, 2, {"input", "views", "overlap-deg", "out"}, {});
  if (!args) return fail(args.error());
  if (!args->has("input") || !args->has("out")) {
    return fail(invalidArgument("usage: fogctl split --input SCAN --views K [--overlap-deg 10] --out DIR"));
  }
  const auto views = args->getInt("views", 4);
  const auto overlap = args->getDouble("overlap-deg", 10.0);
  if (!views || *views < 1 || *views > 64) return fail(invalidArgument("--views must be in [1, 64]"));
  if (!overlap || *overlap < 0.0 || *overlap >= 360.0 / static_cast<double>(*views)) {
    return fail(invalidArgument("--overlap-deg must be in [0, 360 / views)"));
  }
  const auto scan = readCloud(args->get("input"));
  if (!scan) return fail(scan.error());
  const std::filesystem::path out = args->get("out");
  std::error_code ec;
  std::filesystem::create_directories(out, ec);
  if (ec) return fail(ioError("cannot create " + out.string()));
  const auto stem = std::filesystem::path(args->get("input")).stem().string();
  std::printf("# %ld virtual LiDARs cut from %s (%zu points); pose = sensor -> scan frame\n", *views,
              args->get("input").c_str(), scan->points.size());
  for (int k = 0; k < *views; ++k) {
    const SectorSplit split{static_cast<int>(*views), k, *overlap};
    const Cloud view = sectorView(scan->points, split);
    const auto file = out / (stem + "_view" + std::to_string(k) + ".bin");
    if (const Status s = writeKittiBin(file, view); !s) return fail(s.error());
    const double yaw = std::atan2(sectorPose(split).rotation()(1, 0), sectorPose(split).rotation()(0, 0)) * kRadToDeg;
    std::printf("- view: %d\n  file: %s\n  points: %zu\n  pose: {translation_m: [0, 0, 0], rpy_deg: [0, 0, %.3f]}\n", k,
                file.c_str(), view.size(), yaw);
  }
  return 0;
}

}  // namespace

Command splitCommand() {
  return {"split",
          "--input SCAN --views K [--overlap-deg 10] --out DIR   cut a scan into virtual LiDARs",
          "usage: fogctl split --input SCAN --views K [--overlap-deg 10] --out DIR\n"
          "Cuts a scan into K overlapping sectors, one KITTI .bin per virtual LiDAR, and prints their poses.\n",
          runSplit};
}

}  // namespace fogmap::cli
