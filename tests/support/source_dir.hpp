#pragma once
// Paths in the source tree for tests: the repository itself, its bundled data (see
// data/LICENSE.md), the KITTI drive in it and the real scans among them.
#include <filesystem>
#include <string>
#include <vector>

namespace fogmap::test_support {

inline const std::filesystem::path kSourceDir = FOGMAP_SOURCE_DIR;

inline std::filesystem::path dataDir() { return kSourceDir / "data"; }

// The bundled KITTI raw drive: its scans, camera images and calibration.
inline std::filesystem::path kittiSequenceDir() { return dataDir() / "kitti_raw_seq_a"; }

inline std::vector<std::filesystem::path> bundledKittiScans() {
  std::vector<std::filesystem::path> scans;
  for (int i = 0; i < 5; ++i) scans.push_back(kittiSequenceDir() / ("000000000" + std::to_string(i) + ".bin"));
  scans.push_back(dataDir() / "kitti_object" / "velodyne" / "000001.bin");
  scans.push_back(dataDir() / "kitti_object" / "velodyne" / "000002.bin");
  return scans;
}

}  // namespace fogmap::test_support
