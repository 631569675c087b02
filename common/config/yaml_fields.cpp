#include "common/config/yaml_fields.hpp"

#include <algorithm>
#include <cmath>

#include "common/base/angles.hpp"

namespace fogmap {

Eigen::Vector3d rpyDegrees(const Eigen::Matrix3d& r) {
  const double pitch = std::asin(std::clamp(-r(2, 0), -1.0, 1.0));
  double roll = 0.0;
  double yaw = 0.0;
  if (std::abs(r(2, 0)) < 1.0 - 1e-12) {
    roll = std::atan2(r(2, 1), r(2, 2));
    yaw = std::atan2(r(1, 0), r(0, 0));
  } else {  // gimbal lock: only yaw - roll (or yaw + roll) is defined; put it all in yaw
    yaw = std::atan2(-r(0, 1), r(1, 1));
  }
  Eigen::Vector3d out(roll, pitch, yaw);
  out *= kRadToDeg;
  for (int i = 0; i < 3; ++i) {
    if (std::abs(out[i]) < 1e-9) out[i] = 0.0;
  }
  return out;
}

Status YamlFields::checkSection(const YAML::Node& node, const std::string& where,
                                std::initializer_list<std::string_view> keys) const {
  if (!node.IsMap()) return bad(where.empty() ? "the document" : where, "must be a mapping");
  for (const auto& entry : node) {
    const std::string key = entry.first.IsScalar() ? entry.first.Scalar() : std::string("?");
    if (std::find(keys.begin(), keys.end(), key) == keys.end()) {
      return bad(where.empty() ? key : where + "." + key, "unknown key");
    }
  }
  return {};
}

Expected<Eigen::Vector3d> YamlFields::vec3(const YAML::Node& node, const std::string& key, const std::string& where,
                                           const Eigen::Vector3d& fallback) const {
  const YAML::Node v = node[key];
  if (!v) return fallback;
  if (!v.IsSequence() || v.size() != 3) return bad(where + "." + key, "expected a list of 3 numbers");
  Eigen::Vector3d out;
  for (std::size_t i = 0; i < 3; ++i) {
    try {
      out[static_cast<Eigen::Index>(i)] = v[i].as<double>();
    } catch (const YAML::Exception&) {
      return bad(where + "." + key, "expected a list of 3 numbers");
    }
  }
  if (!out.allFinite()) return bad(where + "." + key, "values must be finite");
  return out;
}

Expected<Eigen::Isometry3d> YamlFields::pose(const YAML::Node& node, const std::string& where) const {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  if (!node) return pose;
  if (const Status s = checkSection(node, where, {"translation_m", "rpy_deg"}); !s) return s.error();
  const auto t = vec3(node, "translation_m", where, Eigen::Vector3d::Zero());
  if (!t) return t.error();
  const auto rpy = vec3(node, "rpy_deg", where, Eigen::Vector3d::Zero());
  if (!rpy) return rpy.error();
  const Eigen::Vector3d r = *rpy * kDegToRad;
  pose.linear() = (Eigen::AngleAxisd(r.z(), Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(r.y(), Eigen::Vector3d::UnitY()) *
                   Eigen::AngleAxisd(r.x(), Eigen::Vector3d::UnitX()))
                      .toRotationMatrix();
  pose.translation() = *t;
  return pose;
}

}  // namespace fogmap
