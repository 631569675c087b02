#include "view/live_view.hpp"

#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>
#include <utility>

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include "common/base/angles.hpp"
#include "common/base/text.hpp"
#include "common/config/camera_node.hpp"
#include "common/geometry/geofence.hpp"
#include "common/geometry/object_class.hpp"
#include "common/geometry/object_shape.hpp"
#include "common/geometry/symmetric_eigen.hpp"

namespace fogmap::view {
namespace {

using nlohmann::json;

// Millimetres are finer than anything the page can draw, and keep the events short.
double mm(double metres) { return std::round(metres * 1000.0) / 1000.0; }
double ms(std::int64_t ns) { return static_cast<double>(ns / 1000) / 1000.0; }  // exact to the microsecond
double headingDeg(const Eigen::Vector3d& forward) {
  return std::round(std::atan2(forward.y(), forward.x()) * kRadToDeg * 10.0) / 10.0;
}
json xyz(const Eigen::Vector3d& v) { return json::array({mm(v.x()), mm(v.y()), mm(v.z())}); }

json linkJson(const LinkState& link) {
  return {{"connected", link.connected}, {"target", link.target}, {"detail", link.detail}};
}

}  // namespace

Expected<std::vector<FenceBox>> parseFenceBoxes(const std::string& text) {
  std::vector<FenceBox> fences;
  std::set<std::string> names;
  std::stringstream parts(text);
  std::string part;
  while (std::getline(parts, part, ';')) {
    if (part.empty()) continue;
    const auto equals = part.find('=');
    if (equals == std::string::npos || equals == 0) {
      return invalidArgument("geofence '" + part + "': write it NAME=XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX");
    }
    FenceBox fence;
    fence.name = part.substr(0, equals);
    std::vector<double> values;
    std::stringstream numbers(part.substr(equals + 1));
    std::string number;
    while (std::getline(numbers, number, ',')) {
      char* end = nullptr;
      const double v = std::strtod(number.c_str(), &end);
      if (number.empty() || end != number.c_str() + number.size() || !std::isfinite(v)) {
        return invalidArgument("geofence '" + fence.name + "': '" + number + "' is not a finite number");
      }
      values.push_back(v);
    }
    if (values.size() != 6) {
      return invalidArgument("geofence '" + fence.name + "': needs 6 numbers (XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX), got " +
                             std::to_string(values.size()));
    }
    fence.min = {values[0], values[1], values[2]};
    fence.max = {values[3], values[4], values[5]};
    if ((fence.min.array() >= fence.max.array()).any()) {
      return invalidArgument("geofence '" + fence.name + "': the minimum must be below the maximum on every axis");
    }
    if (!names.insert(fence.name).second) return invalidArgument("geofence '" + fence.name + "' is given twice");
    if (auto valid = validateGeofence(boxGeofence(fence.name, fence.min, fence.max)); !valid) {
      return invalidArgument("geofence '" + fence.name + "': " + valid.error().message);
    }
    fences.push_back(std::move(fence));
  }
  return fences;
}

ViewConfig viewConfigOf(const TopologyConfig& topology, std::vector<FenceBox> geofences) {
  ViewConfig config;
  config.topology = topology.name;
  config.geofences = std::move(geofences);
  for (const auto& node : topology.nodes) {
    config.nodes.push_back({node.id, node.name, roleName(node.role)});
    if (node.role == Role::kTracker) config.has_tracker = true;
    if (node.sensor) {
      const Eigen::Isometry3d& pose = node.sensor->pose;
      config.sensors.push_back({node.name, "lidar", pose.translation(), headingDeg(pose.linear().col(0))});
    }
    if (node.camera) {
      // world_to_camera's inverse is the camera's pose; the camera looks along its z axis.
      const Eigen::Isometry3d pose = node.camera->calibration.world_to_camera.inverse();
      config.sensors.push_back({node.name, "camera", pose.translation(), headingDeg(pose.linear().col(2))});
    }
  }
  return config;
}

GroundEllipse groundEllipse(const Ellipsoid& ellipsoid) {
  // The shadow of {x : (x - c)^T S^-1 (x - c) <= 1} on the ground is the ellipse of the marginal
  // block S_xy: its eigenvalues are the squared semi-axes.
  const Eigen::Matrix2d block = ellipsoid.shape.topLeftCorner<2, 2>();
  const SymmetricEigen<2> eigen = symmetricEigen(block);
  const Eigen::Vector2d values = eigen.values.cwiseMax(0.0);  // ascending
  const Eigen::Vector2d major = eigen.vectors.col(1);
  GroundEllipse out;
  out.centre = ellipsoid.center.head<2>();
  out.a = std::sqrt(values(1));
  out.b = std::sqrt(values(0));
  double angle = std::atan2(major.y(), major.x());
  if (angle <= -std::numbers::pi / 2) angle += std::numbers::pi;
  if (angle > std::numbers::pi / 2) angle -= std::numbers::pi;
  out.angle_rad = angle;
  return out;
}

LiveView::LiveView(ViewConfig config, std::size_t trail_points, std::size_t max_trails)
    : config_(std::move(config)), trail_points_(std::max<std::size_t>(1, trail_points)), max_trails_(max_trails) {
  for (const auto& node : config_.nodes) node_names_[node.id] = node.name;
}

std::string LiveView::nodeName(std::uint32_t id) const {
  const auto it = node_names_.find(id);
  return it != node_names_.end() ? it->second : "node " + std::to_string(id);
}

std::string LiveView::configEvent() const {
  json sensors = json::array();
  for (const auto& s : config_.sensors) {
    sensors.push_back({{"name", s.name}, {"kind", s.kind}, {"x", mm(s.position.x())}, {"y", mm(s.position.y())},
                       {"z", mm(s.position.z())}, {"heading_deg", s.heading_deg}});
  }
  json fences = json::array();
  for (const auto& f : config_.geofences) fences.push_back({{"name", f.name}, {"min", xyz(f.min)}, {"max", xyz(f.max)}});
  json nodes = json::array();
  for (const auto& n : config_.nodes) nodes.push_back({{"id", n.id}, {"name", n.name}, {"role", n.role}});
  return json{{"topology", config_.topology}, {"sensors", std::move(sensors)}, {"geofences", std::move(fences)},
              {"nodes", std::move(nodes)}, {"has_tracker", config_.has_tracker}}
      .dump(-1, ' ', false, json::error_handler_t::replace);
}

std::string LiveView::mapEvent(const GlobalMapMessage& global) {
  const auto& header = global.header;
  for (const auto node : header.contributing_nodes) {
    auto& last = last_epoch_[node];
    last = std::max(last, header.epoch);
  }
  json objects = json::array();
  for (std::size_t k = 0; k < global.map.objects.size(); ++k) {
    const MapObject& object = global.map.objects[k];
    json ellipses = json::array();
    std::set<std::string> sensors;
    for (const auto& e : object.ellipsoids) {
      const GroundEllipse g = groundEllipse(e);
      const std::string sensor = nodeName(e.node());
      sensors.insert(sensor);
      ellipses.push_back({{"cx", mm(g.centre.x())}, {"cy", mm(g.centre.y())}, {"a", mm(g.a)}, {"b", mm(g.b)},
                          {"angle_deg", std::round(g.angle_rad * kRadToDeg * 10.0) / 10.0}, {"sensor", sensor},
                          {"points", e.point_count}});
    }
    json box = nullptr;
    if (const auto b = objectBox(object)) {
      box = {{"cx", mm(b->centre.x())}, {"cy", mm(b->centre.y())}, {"length", mm(b->length)}, {"width", mm(b->width)},
             {"yaw_deg", std::round(b->yaw * kRadToDeg * 10.0) / 10.0}, {"zmin", mm(b->centre.z() - b->height / 2)},
             {"zmax", mm(b->centre.z() + b->height / 2)}};
    }
    json object_class = nullptr;
    json confidence = nullptr;
    if (const auto label = objectLabel(object)) {
      object_class = std::string(objectClassName(label->object_class));
      confidence = std::round(label->confidence * 100.0) / 100.0;
    }
    objects.push_back({{"id", k}, {"points", object.pointCount()}, {"sensors", sensors}, {"class", object_class},
                       {"confidence", confidence}, {"box", box},
                       {"extent", {{"min", xyz(object.box.min)}, {"max", xyz(object.box.max)}}},
                       {"ellipses", std::move(ellipses)}});
  }
  json fences = json::array();
  for (const auto& f : config_.geofences) {
    json inside = json::array();
    for (const auto& hit : intrusions(global.map, boxGeofence(f.name, f.min, f.max))) inside.push_back(hit.object_index);
    fences.push_back({{"name", f.name}, {"occupied", !inside.empty()}, {"objects", std::move(inside)}});
  }
  // Every node the root expects: those in this map and those missing from it.
  std::set<std::uint32_t> expected(header.contributing_nodes.begin(), header.contributing_nodes.end());
  expected.insert(header.missing_nodes.begin(), header.missing_nodes.end());
  const std::set<std::uint32_t> missing(header.missing_nodes.begin(), header.missing_nodes.end());
  json nodes = json::array();
  for (const auto id : expected) {
    const auto last = last_epoch_.find(id);
    nodes.push_back({{"id", id}, {"name", nodeName(id)}, {"missing", missing.count(id) > 0},
                     {"last_epoch", last != last_epoch_.end() ? json(last->second) : json(nullptr)}});
  }
  return json{{"epoch", header.epoch},  {"revision", global.revision},      {"late", global.late},
              {"published_ms", ms(global.published_time_ns)}, {"sensor_ms", ms(header.sensor_time_ns)},
              {"objects", std::move(objects)}, {"geofences", std::move(fences)}, {"nodes", std::move(nodes)}}
      .dump(-1, ' ', false, json::error_handler_t::replace);
}

std::string LiveView::tracksEvent(const tracking::TrackSnapshot& snapshot) {
  // The trails of tracks that ended go first: their places are free for new tracks.
  std::set<std::uint64_t> live;
  for (const auto& t : snapshot.tracks) live.insert(t.id);
  std::erase_if(trails_, [&](const auto& entry) { return live.count(entry.first) == 0; });
  json tracks = json::array();
  for (const auto& t : snapshot.tracks) {
    auto trail = trails_.find(t.id);
    if (trail == trails_.end() && trails_.size() < max_trails_) trail = trails_.emplace(t.id, std::deque<Eigen::Vector2d>{}).first;
    json points = json::array();
    if (trail != trails_.end()) {
      trail->second.push_back(t.position);
      while (trail->second.size() > trail_points_) trail->second.pop_front();
      for (const auto& p : trail->second) points.push_back(json::array({mm(p.x()), mm(p.y())}));
    }
    json heading = nullptr;
    if (t.heading_rad) heading = std::round(*t.heading_rad * kRadToDeg * 10.0) / 10.0;
    tracks.push_back({{"id", t.id}, {"label", t.label}, {"state", tracking::trackStateName(t.state)},
                      {"x", mm(t.position.x())}, {"y", mm(t.position.y())}, {"vx", mm(t.velocity.x())},
                      {"vy", mm(t.velocity.y())}, {"heading_deg", heading}, {"camera", t.camera_confirmed},
                      {"sigma_m", mm(std::sqrt(std::max(0.0, t.covariance.trace() / 2.0)))}, {"trail", std::move(points)}});
  }
  return json{{"published_ms", ms(snapshot.published_time_ns)}, {"lidar_ms", ms(snapshot.lidar_time_ns)},
              {"association", tracking::associationName(snapshot.association)}, {"tracks", std::move(tracks)}}
      .dump(-1, ' ', false, json::error_handler_t::replace);
}

std::string LiveView::statusEvent(const LinkState& root, const std::optional<LinkState>& tracker, std::uint64_t skipped_events,
                                  std::int64_t now_ns) const {
  return json{{"root", linkJson(root)}, {"tracker", tracker ? linkJson(*tracker) : json(nullptr)},
              {"skipped_events", skipped_events}, {"server_ms", ms(now_ns)}}
      .dump(-1, ' ', false, json::error_handler_t::replace);
}

}  // namespace fogmap::view
