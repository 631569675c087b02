#pragma once
// Inside the topology parser (topology_parse.cpp, topology_sections.cpp, topology_validate.cpp),
// not for use outside common/config: the field reader whose errors name the place in the file, one
// reader per section, and the checks across nodes.
#include <filesystem>
#include <initializer_list>
#include <string>
#include <string_view>

#include <Eigen/Geometry>
#include <yaml-cpp/yaml.h>

#include "common/base/status.hpp"
#include "common/config/camera_node.hpp"
#include "common/config/displacement_node.hpp"
#include "common/config/topology.hpp"
#include "common/config/tracker_node.hpp"
#include "common/config/yaml_fields.hpp"

namespace fogmap::topology_detail {

// Errors name the place in the file: "topology: nodes[3].sensor.rate_hz: must be positive".
inline const YamlFields kFields("topology");

inline Error bad(const std::string& where, const std::string& what) { return kFields.bad(where, what); }

template <class T>
Expected<T> scalar(const YAML::Node& node, const std::string& key, const std::string& where, T fallback) {
  return kFields.scalar<T>(node, key, where, fallback);
}

inline Status checkSection(const YAML::Node& node, const std::string& where,
                           std::initializer_list<std::string_view> keys) {
  return kFields.checkSection(node, where, keys);
}

inline Expected<Eigen::Vector3d> vec3(const YAML::Node& node, const std::string& key, const std::string& where,
                                      const Eigen::Vector3d& fallback) {
  return kFields.vec3(node, key, where, fallback);
}

inline Expected<Eigen::Isometry3d> parsePose(const YAML::Node& node, const std::string& where) {
  return kFields.pose(node, where);
}

// The sections of a node and the top-level `tls:`; `where` names the section in errors
// ("nodes[3].camera"), relative paths resolve against `base_dir`.
Expected<SensorConfig> parseSensor(const YAML::Node& node, const std::string& where, const std::filesystem::path& base_dir);
// The calibration takes the node's name.
Expected<CameraNodeConfig> parseCamera(const YAML::Node& node, const std::string& where, const std::filesystem::path& base_dir,
                                       const std::string& node_name);
Expected<TrackerNodeConfig> parseTracker(const YAML::Node& node, const std::string& where);
Expected<DisplacementNodeConfig> parseDisplacement(const YAML::Node& node, const std::string& where);
Expected<TlsConfig> parseTls(const YAML::Node& node, const std::filesystem::path& base_dir);
Expected<TlsFiles> parseNodeTls(const YAML::Node& node, const std::string& where, const std::filesystem::path& base_dir);

// The rules across nodes (parseTopology's comment): unique names, ids and ports, one root, parents
// and cycles, sections that fit their roles, displacement centroids and their trackers, TLS names.
Status validateTopology(const TopologyConfig& topology);

}  // namespace fogmap::topology_detail
