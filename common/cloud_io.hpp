#pragma once
// Reading and writing point clouds: KITTI .bin, nuScenes .pcd.bin, PCD (ascii, binary,
// binary_compressed). Malformed files are rejected with an error naming the file and the problem;
// non-finite points are dropped and counted.
#include <cstddef>
#include <filesystem>

#include "common/cloud.hpp"
#include "common/status.hpp"

namespace fogmap {

struct LoadedCloud {
  Cloud points;
  std::size_t dropped_non_finite = 0;  // points with a NaN or infinite coordinate, not in `points`
};

enum class CloudFormat { kKittiBin, kNuscenesBin, kPcd };

// Format from the file name: "*.pcd.bin" nuScenes, "*.bin" KITTI, "*.pcd" PCD.
Expected<CloudFormat> cloudFormatFromPath(const std::filesystem::path& path);

// Reads a KITTI velodyne scan: little-endian float32 x, y, z, reflectance (16 bytes a point).
Expected<LoadedCloud> readKittiBin(const std::filesystem::path& path);
// Reads a nuScenes LIDAR_TOP sweep: float32 x, y, z, intensity, ring (20 bytes a point).
Expected<LoadedCloud> readNuscenesBin(const std::filesystem::path& path);
// Reads a PCD file with at least fields x, y, z (intensity optional).
Expected<LoadedCloud> readPcd(const std::filesystem::path& path);
// Reads any supported format, chosen by cloudFormatFromPath.
Expected<LoadedCloud> readCloud(const std::filesystem::path& path);

// Writes a KITTI .bin file (16 bytes a point).
Status writeKittiBin(const std::filesystem::path& path, const Cloud& cloud);
// Writes a binary PCD file with fields x y z intensity.
Status writePcd(const std::filesystem::path& path, const Cloud& cloud);

}  // namespace fogmap
