#pragma once
// Reading fields of a YAML document (topology, scene) with errors that name the place in the file:
// "topology: nodes[3].sensor.rate_hz: must be positive". One reader per document kind.
#include <initializer_list>
#include <string>
#include <string_view>

#include <Eigen/Geometry>
#include <yaml-cpp/yaml.h>

#include "common/base/status.hpp"

namespace fogmap {

// The angles YamlFields::pose reads, from a rotation: [roll, pitch, yaw] in degrees with
// R = Rz(yaw) Ry(pitch) Rx(roll), pitch in [-90, 90], values within 1e-9 of 0 written as 0.
Eigen::Vector3d rpyDegrees(const Eigen::Matrix3d& rotation);

class YamlFields {
 public:
  // `document` prefixes every error ("topology", "scene").
  explicit YamlFields(std::string document) : document_(std::move(document)) {}

  Error bad(const std::string& where, const std::string& what) const {
    return invalidArgument(document_ + ": " + where + ": " + what);
  }

  // node[key] as T, `fallback` when absent, an error naming where.key when it is not a T.
  template <class T>
  Expected<T> scalar(const YAML::Node& node, const std::string& key, const std::string& where, T fallback) const {
    const YAML::Node v = node[key];
    if (!v) return fallback;
    try {
      return v.as<T>();
    } catch (const YAML::Exception&) {
      return bad(where.empty() ? key : where + "." + key, "cannot read '" + YAML::Dump(v) + "' as the expected type");
    }
  }

  // A section must be a mapping of known keys: a misspelt key is an error, not a silent default.
  Status checkSection(const YAML::Node& node, const std::string& where, std::initializer_list<std::string_view> keys) const;
  // node[key] as a list of 3 finite numbers, `fallback` when absent.
  Expected<Eigen::Vector3d> vec3(const YAML::Node& node, const std::string& key, const std::string& where,
                                 const Eigen::Vector3d& fallback) const;
  // {translation_m: [x, y, z], rpy_deg: [roll, pitch, yaw]} (rotation Rz(yaw) Ry(pitch) Rx(roll));
  // the identity when the node is absent.
  Expected<Eigen::Isometry3d> pose(const YAML::Node& node, const std::string& where) const;

 private:
  std::string document_;
};

}  // namespace fogmap
