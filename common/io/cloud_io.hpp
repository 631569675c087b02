#pragma once
// Reading and writing point clouds: KITTI .bin, nuScenes .pcd.bin, PCD (ascii, binary,
// binary_compressed). Malformed files are rejected with an error naming the file and the problem;
// non-finite points are dropped (or kept in place on request) and counted; files above
// ReadLimits::max_bytes are refused unread.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

#include "common/base/status.hpp"
#include "common/geometry/cloud.hpp"

namespace fogmap {

struct LoadedCloud {
  Cloud points;
  std::size_t dropped_non_finite = 0;  // points with a NaN or infinite coordinate, not in `points`
  std::size_t kept_non_finite = 0;     // such points kept in `points` (ReadLimits::keep_non_finite)
  // Zero bytes after a PCD's declared points (an export artefact PCL also ignores): accepted, and
  // reported so the caller can warn and count.
  std::size_t trailing_zero_bytes = 0;
};

// A scan larger than this is refused before it is read: 256 MiB is 16 million KITTI points,
// far above any real sensor's frame.
inline constexpr std::uintmax_t kDefaultMaxScanBytes = 256ULL << 20;

struct ReadLimits {
  std::uintmax_t max_bytes = kDefaultMaxScanBytes;  // file size bound (topology max_scan_bytes)
  // Keep non-finite points in place (counted in kept_non_finite) instead of dropping them, so that
  // `points` lines up with the file's points one to one (fogctl cluster --labels).
  bool keep_non_finite = false;
};

enum class CloudFormat { kKittiBin, kNuscenesBin, kPcd };

// Format from the file name: "*.pcd.bin" nuScenes, "*.bin" KITTI, "*.pcd" PCD.
Expected<CloudFormat> cloudFormatFromPath(const std::filesystem::path& path);

// Reads a KITTI velodyne scan: little-endian float32 x, y, z, reflectance (16 bytes a point).
Expected<LoadedCloud> readKittiBin(const std::filesystem::path& path, const ReadLimits& limits = {});
// Reads a nuScenes LIDAR_TOP sweep: float32 x, y, z, intensity, ring (20 bytes a point).
Expected<LoadedCloud> readNuscenesBin(const std::filesystem::path& path, const ReadLimits& limits = {});
// Reads a PCD file with at least fields x, y, z (intensity optional). Zero bytes after the declared
// data are accepted and counted in trailing_zero_bytes; any other trailing byte is an error.
Expected<LoadedCloud> readPcd(const std::filesystem::path& path, const ReadLimits& limits = {});
// The same readers over bytes already in memory (the file readers read the file and call these).
// `name`, the file's path or whatever the bytes came from, starts every error message.
Expected<LoadedCloud> parseKittiBin(std::string_view bytes, const std::string& name, const ReadLimits& limits = {});
Expected<LoadedCloud> parseNuscenesBin(std::string_view bytes, const std::string& name, const ReadLimits& limits = {});
Expected<LoadedCloud> parsePcd(std::string_view bytes, const std::string& name, const ReadLimits& limits = {});
// Reads any supported format, chosen by cloudFormatFromPath.
Expected<LoadedCloud> readCloud(const std::filesystem::path& path, const ReadLimits& limits = {});

// Writes a KITTI .bin file (16 bytes a point).
Status writeKittiBin(const std::filesystem::path& path, const Cloud& cloud);
// Writes a binary PCD file with fields x y z intensity.
Status writePcd(const std::filesystem::path& path, const Cloud& cloud);

}  // namespace fogmap
