#include "common/camera/kitti.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <sstream>

namespace fogmap::camera {
namespace {

// "KEY: n1 n2 ..." lines into key -> numbers; a value that is not a number is an error.
Expected<std::map<std::string, std::vector<double>>> keyedNumbers(const std::string& text) {
  std::map<std::string, std::vector<double>> out;
  std::istringstream lines(text);
  std::string line;
  for (int number = 1; std::getline(lines, line); ++number) {
    const auto colon = line.find(':');
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    if (colon == std::string::npos) return invalidArgument("calib line " + std::to_string(number) + ": no 'KEY:'");
    std::istringstream values(line.substr(colon + 1));
    std::vector<double> numbers;
    std::string word;
    while (values >> word) {
      char* end = nullptr;
      const double v = std::strtod(word.c_str(), &end);
      if (end == word.c_str() || *end != '\0' || !std::isfinite(v)) {
        return invalidArgument("calib line " + std::to_string(number) + ": '" + word + "' is not a number");
      }
      numbers.push_back(v);
    }
    out[line.substr(0, colon)] = std::move(numbers);
  }
  return out;
}

}  // namespace

Eigen::Vector3d KittiCalibration::velodyneToRectified(const Eigen::Vector3d& point) const {
  return rectification * (velodyne_to_camera * point);
}

Expected<KittiCalibration> parseKittiCalibration(const std::string& text) {
  auto keyed = keyedNumbers(text);
  if (!keyed) return keyed.error();
  const auto numbers = [&](const std::string& key, std::size_t count) -> Expected<const std::vector<double>*> {
    const auto it = keyed->find(key);
    if (it == keyed->end()) return invalidArgument("calib: no " + key);
    if (it->second.size() != count) {
      return invalidArgument("calib: " + key + " has " + std::to_string(it->second.size()) + " numbers, not " +
                             std::to_string(count));
    }
    return &it->second;
  };
  KittiCalibration calib;
  for (int i = 0; i < 4; ++i) {
    std::string key = "P";
    key += std::to_string(i);
    const auto p = numbers(key, 12);
    if (!p) return p.error();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) calib.projection[static_cast<std::size_t>(i)](r, c) = (**p)[static_cast<std::size_t>(4 * r + c)];
    }
  }
  const auto r0 = numbers("R0_rect", 9);
  if (!r0) return r0.error();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) calib.rectification(r, c) = (**r0)[static_cast<std::size_t>(3 * r + c)];
  }
  const auto tr = numbers("Tr_velo_to_cam", 12);
  if (!tr) return tr.error();
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) m(r, c) = (**tr)[static_cast<std::size_t>(4 * r + c)];
  }
  calib.velodyne_to_camera.matrix() = m;
  return calib;
}

Expected<PinholeCamera> pinholeCamera(const KittiCalibration& calibration, int index, int width, int height) {
  if (index < 0 || index > 3) return invalidArgument("calib: camera " + std::to_string(index) + " does not exist (P0..P3)");
  const std::string p = "calib: P" + std::to_string(index);
  const Eigen::Matrix<double, 3, 4>& projection = calibration.projection[static_cast<std::size_t>(index)];
  const Eigen::Matrix3d k = projection.leftCols<3>();
  // K [I | t]: intrinsics on the left (no skew), the rectified frame's offset to this camera in t.
  constexpr double kTolerance = 1e-9;
  if (std::abs(k(0, 1)) > kTolerance || std::abs(k(1, 0)) > kTolerance || std::abs(k(2, 0)) > kTolerance ||
      std::abs(k(2, 1)) > kTolerance || std::abs(k(2, 2) - 1.0) > kTolerance) {
    return invalidArgument(p + " is not of the form K [I | t] with K = [fx 0 cx; 0 fy cy; 0 0 1]");
  }
  PinholeCamera camera;
  camera.name = "P" + std::to_string(index);
  camera.fx = k(0, 0);
  camera.fy = k(1, 1);
  camera.cx = k(0, 2);
  camera.cy = k(1, 2);
  camera.width = width;
  camera.height = height;
  const Eigen::Vector3d offset = k.inverse() * projection.col(3);
  Eigen::Isometry3d velodyne_to_camera = Eigen::Isometry3d::Identity();
  velodyne_to_camera.linear() = calibration.rectification * calibration.velodyne_to_camera.linear();
  velodyne_to_camera.translation() = calibration.rectification * calibration.velodyne_to_camera.translation() + offset;
  camera.world_to_camera = velodyne_to_camera;
  if (const Status valid = validate(camera); !valid) return invalidArgument(p + ": " + valid.error().message);
  return camera;
}

Expected<std::vector<KittiLabel>> parseKittiLabels(const std::string& text) {
  std::vector<KittiLabel> labels;
  std::istringstream lines(text);
  std::string line;
  for (int number = 1; std::getline(lines, line); ++number) {
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    std::istringstream fields(line);
    KittiLabel l;
    double occluded = 0.0;
    double h = 0.0, w = 0.0, len = 0.0, x = 0.0, y = 0.0, z = 0.0;
    if (!(fields >> l.type >> l.truncated >> occluded >> l.alpha >> l.box.left >> l.box.top >> l.box.right >> l.box.bottom >>
          h >> w >> len >> x >> y >> z >> l.rotation_y)) {
      return invalidArgument("label line " + std::to_string(number) + ": expected 15 fields (type, truncation, occlusion, "
                             "alpha, 2D box, h w l, x y z, rotation_y)");
    }
    l.occluded = static_cast<int>(occluded);
    l.size_hwl = {h, w, len};
    l.location = {x, y, z};
    labels.push_back(std::move(l));
  }
  return labels;
}

std::array<Eigen::Vector3d, 8> boxCorners(const KittiLabel& label) {
  const double h = label.size_hwl.x();
  const double w = label.size_hwl.y();
  const double l = label.size_hwl.z();
  // Yaw about y: the box's length runs along its x.
  const Eigen::Matrix3d turn = Eigen::AngleAxisd(label.rotation_y, Eigen::Vector3d::UnitY()).toRotationMatrix();
  std::array<Eigen::Vector3d, 8> corners;
  const double xs[4] = {l / 2, l / 2, -l / 2, -l / 2};
  const double zs[4] = {w / 2, -w / 2, -w / 2, w / 2};
  for (std::size_t i = 0; i < 4; ++i) {
    corners[i] = label.location + turn * Eigen::Vector3d(xs[i], 0.0, zs[i]);     // bottom (y grows downwards)
    corners[i + 4] = label.location + turn * Eigen::Vector3d(xs[i], -h, zs[i]);  // top
  }
  return corners;
}

VelodyneBox labelBoxInVelodyne(const KittiLabel& label, const KittiCalibration& calibration) {
  Eigen::Isometry3d rect_to_velodyne = Eigen::Isometry3d::Identity();
  rect_to_velodyne.linear() = calibration.rectification * calibration.velodyne_to_camera.linear();
  rect_to_velodyne.translation() = calibration.rectification * calibration.velodyne_to_camera.translation();
  rect_to_velodyne = rect_to_velodyne.inverse();
  VelodyneBox box;
  box.corners = boxCorners(label);
  for (auto& c : box.corners) c = rect_to_velodyne * c;
  for (const auto& c : box.corners) box.centre += c / 8.0;
  // boxCorners: corners 1 -> 2 run along the length, 0 -> 1 across it, 0 -> 4 up.
  const Eigen::Vector3d along = box.corners[1] - box.corners[2];
  box.length = label.size_hwl.z();
  box.width = label.size_hwl.y();
  box.height = label.size_hwl.x();
  box.yaw = std::atan2(along.y(), along.x());
  return box;
}

bool VelodyneBox::contains(const Eigen::Vector3d& point) const {
  const double c = std::cos(yaw), s = std::sin(yaw);
  const double dx = point.x() - centre.x(), dy = point.y() - centre.y();
  return std::abs(c * dx + s * dy) <= 0.5 * length && std::abs(-s * dx + c * dy) <= 0.5 * width &&
         std::abs(point.z() - centre.z()) <= 0.5 * height;
}

std::optional<Eigen::Vector2d> projectPoint(const Eigen::Matrix<double, 3, 4>& projection, const Eigen::Vector3d& point,
                                            double near_m) {
  if (!(point.z() >= near_m)) return std::nullopt;
  const Eigen::Vector3d p = projection * point.homogeneous();
  if (!(p.z() > 0.0)) return std::nullopt;
  return Eigen::Vector2d(p.x() / p.z(), p.y() / p.z());
}

std::optional<Box2d> projectBox(const Eigen::Matrix<double, 3, 4>& projection, const std::array<Eigen::Vector3d, 8>& corners,
                                int width, int height) {
  Box2d box{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
            -std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
  for (const auto& corner : corners) {
    const auto pixel = projectPoint(projection, corner);
    if (!pixel) return std::nullopt;
    box.left = std::min(box.left, pixel->x());
    box.top = std::min(box.top, pixel->y());
    box.right = std::max(box.right, pixel->x());
    box.bottom = std::max(box.bottom, pixel->y());
  }
  box.left = std::max(box.left, 0.0);
  box.top = std::max(box.top, 0.0);
  box.right = std::min(box.right, static_cast<double>(width - 1));
  box.bottom = std::min(box.bottom, static_cast<double>(height - 1));
  if (box.left >= box.right || box.top >= box.bottom) return std::nullopt;
  return box;
}

}  // namespace fogmap::camera
