#include "common/perception/lidar_models.hpp"

namespace fogmap {
namespace {

// `count` angles from `first` in steps of `step` degrees.
std::vector<double> evenly(double first, double step, int count) {
  std::vector<double> out;
  for (int i = 0; i < count; ++i) out.push_back(first + step * i);
  return out;
}

LidarModel vlp16() {
  // Velodyne VLP-16 user manual: 16 lasers, +-15 degrees in 2 degree steps, 0.2 degree azimuth
  // resolution at 10 Hz (1,800 firings per revolution), 100 m range.
  return {"VLP-16", evenly(-15.0, 2.0, 16), 1800, 10.0, 0.5, 100.0};
}

LidarModel hdl32e() {
  // Velodyne HDL-32E manual: 32 lasers from -30.67 to +10.67 degrees (1.33 degree spacing),
  // about 0.16 degree azimuth resolution at 10 Hz, 100 m range.
  return {"HDL-32E", evenly(-92.0 / 3.0, 4.0 / 3.0, 32), 2250, 10.0, 1.0, 100.0};  // -30.67 .. +10.67
}

LidarModel hdl64e() {
  // Velodyne HDL-64E S2 (KITTI): upper block of 32 lasers from +2 to -8.33 degrees (1/3 degree
  // spacing), lower block of 32 from -8.83 to -24.33 degrees (1/2 degree spacing); about 0.08 to
  // 0.09 degree azimuth resolution at 10 Hz (KITTI scans hold about 2,000 points per ring);
  // 120 m range.
  std::vector<double> angles = evenly(2.0, -1.0 / 3.0, 32);
  const std::vector<double> lower = evenly(-8.83, -0.5, 32);
  angles.insert(angles.end(), lower.begin(), lower.end());
  return {"HDL-64E", angles, 2048, 10.0, 1.0, 120.0};
}

LidarModel os1_64() {
  // Ouster OS1-64 (gen 1) datasheet: 64 channels evenly over a 33.2 degree vertical field of view
  // (+16.6 to -16.6 degrees), 2048 columns at 10 Hz, 120 m range.
  return {"OS1-64", evenly(16.6, -33.2 / 63.0, 64), 2048, 10.0, 0.8, 120.0};
}

}  // namespace

std::vector<std::string> lidarModelNames() { return {"VLP-16", "HDL-32E", "HDL-64E", "OS1-64"}; }

Expected<LidarModel> lidarModel(const std::string& name) {
  if (name == "VLP-16") return vlp16();
  if (name == "HDL-32E") return hdl32e();
  if (name == "HDL-64E") return hdl64e();
  if (name == "OS1-64") return os1_64();
  std::string known;
  for (const auto& n : lidarModelNames()) known += (known.empty() ? "" : ", ") + n;
  return Error{ErrorCode::kNotFound, "no LiDAR model '" + name + "' (known: " + known + ")"};
}

}  // namespace fogmap
