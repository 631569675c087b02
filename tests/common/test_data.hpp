#pragma once
// Paths of the real scans bundled with the repository (see data/LICENSE.md).
#include <filesystem>
#include <string>
#include <vector>

namespace fogmap::testing {

inline std::filesystem::path dataDir() { return std::filesystem::path(FOGMAP_SOURCE_DIR) / "data"; }

inline std::vector<std::filesystem::path> bundledKittiScans() {
  std::vector<std::filesystem::path> scans;
  for (int i = 0; i < 5; ++i) scans.push_back(dataDir() / "kitti_raw_seq_a" / ("000000000" + std::to_string(i) + ".bin"));
  scans.push_back(dataDir() / "kitti_object" / "velodyne" / "000001.bin");
  scans.push_back(dataDir() / "kitti_object" / "velodyne" / "000002.bin");
  return scans;
}

}  // namespace fogmap::testing
