#include "services/common/proto_convert.hpp"

// Cameras and tracks: detection frames, centroid frames and tracks (the declarations and their
// bounds are in proto_convert.hpp).
#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <utility>

#include "common/config/topology.hpp"
#include "common/geometry/symmetric_eigen.hpp"

namespace fogmap {

v1::DetectionFrame toProto(const tracking::DetectionFrame& frame) {
  v1::DetectionFrame out;
  out.set_camera(frame.camera);
  out.set_capture_time_ns(frame.capture_time_ns);
  for (const auto& d : frame.detections) {
    auto* p = out.add_detections();
    p->set_left(static_cast<float>(d.box.left));
    p->set_top(static_cast<float>(d.box.top));
    p->set_right(static_cast<float>(d.box.right));
    p->set_bottom(static_cast<float>(d.box.bottom));
    p->set_label(d.label);
    p->set_score(static_cast<float>(d.score));
  }
  return out;
}

Expected<tracking::DetectionFrame> fromProto(const v1::DetectionFrame& frame) {
  if (!isName(frame.camera())) return invalidArgument("detection frame: camera '" + frame.camera().substr(0, 64) + "' is not a node name");
  if (frame.detections_size() > kMaxDetectionsPerFrame) {
    return resourceExhausted("detection frame: " + std::to_string(frame.detections_size()) + " detections, more than " +
                           std::to_string(kMaxDetectionsPerFrame));
  }
  tracking::DetectionFrame out;
  out.camera = frame.camera();
  out.capture_time_ns = frame.capture_time_ns();
  out.detections.reserve(static_cast<std::size_t>(frame.detections_size()));
  constexpr double kMaxPixel = 1e6;
  for (int i = 0; i < frame.detections_size(); ++i) {
    const auto& d = frame.detections(i);
    const std::string where = "detection frame: detections[" + std::to_string(i) + "]";
    for (const float v : {d.left(), d.top(), d.right(), d.bottom()}) {
      if (!std::isfinite(v) || std::abs(v) > kMaxPixel) return invalidArgument(where + ": box coordinates must be finite pixels");
    }
    if (d.left() > d.right() || d.top() > d.bottom()) return invalidArgument(where + ": box has left > right or top > bottom");
    if (!std::isfinite(d.score())) return invalidArgument(where + ": score must be finite");
    const bool printable = std::all_of(d.label().begin(), d.label().end(), [](char c) { return c >= 0x20 && c < 0x7f; });
    if (d.label().empty() || d.label().size() > 64 || !printable) {
      return invalidArgument(where + ": label must be 1 to 64 printable characters");
    }
    camera::Detection detection;
    detection.box = {d.left(), d.top(), d.right(), d.bottom()};
    detection.label = d.label();
    detection.score = d.score();
    detection.camera = out.camera;
    detection.capture_time_ns = out.capture_time_ns;
    out.detections.push_back(std::move(detection));
  }
  return out;
}

v1::CentroidFrame toProto(const tracking::CentroidFrame& frame) {
  v1::CentroidFrame out;
  out.set_edge(frame.edge);
  out.set_epoch(frame.epoch);
  out.set_sensor_time_ns(frame.time_ns);
  toProto(frame.sensor_position, out.mutable_sensor_position());
  for (const auto& c : frame.centroids) {
    auto* p = out.add_centroids();
    for (int i = 0; i < 3; ++i) p->add_position(static_cast<float>(c.position(i)));
    const Eigen::Matrix3d& m = c.covariance;
    for (const double v : {m(0, 0), m(0, 1), m(0, 2), m(1, 1), m(1, 2), m(2, 2)}) p->add_covariance(static_cast<float>(v));
    p->set_point_count(c.point_count);
  }
  return out;
}

Expected<tracking::CentroidFrame> fromProto(const v1::CentroidFrame& frame) {
  if (!isName(frame.edge())) return invalidArgument("centroid frame: edge '" + frame.edge().substr(0, 64) + "' is not a node name");
  if (frame.centroids_size() > kMaxCentroidsPerFrame) {
    return resourceExhausted("centroid frame: " + std::to_string(frame.centroids_size()) + " centroids, more than " +
                           std::to_string(kMaxCentroidsPerFrame));
  }
  const auto within = [](const Eigen::Vector3d& v) { return v.allFinite() && v.cwiseAbs().maxCoeff() <= kMaxCentroidCoordinateM; };
  tracking::CentroidFrame out;
  out.edge = frame.edge();
  out.epoch = frame.epoch();
  out.time_ns = frame.sensor_time_ns();
  out.sensor_position = fromProto(frame.sensor_position());
  if (!within(out.sensor_position)) return invalidArgument("centroid frame: sensor_position must be finite, within 1e6 m");
  out.centroids.reserve(static_cast<std::size_t>(frame.centroids_size()));
  for (int i = 0; i < frame.centroids_size(); ++i) {
    const auto& c = frame.centroids(i);
    const std::string where = "centroid frame: centroids[" + std::to_string(i) + "]";
    if (c.position_size() != 3) {
      return invalidArgument(where + ": position has " + std::to_string(c.position_size()) + " values, expected 3 (x y z)");
    }
    if (c.covariance_size() != 6) {
      return invalidArgument(where + ": covariance has " + std::to_string(c.covariance_size()) +
                             " values, expected 6 (upper triangle xx xy xz yy yz zz)");
    }
    tracking::DisplacementCentroid centroid;
    centroid.position = {c.position(0), c.position(1), c.position(2)};
    if (!within(centroid.position)) return invalidArgument(where + ": position must be finite, within 1e6 m");
    const auto& v = c.covariance();
    centroid.covariance << v[0], v[1], v[2],  //
        v[1], v[3], v[4],                     //
        v[2], v[4], v[5];
    if (!centroid.covariance.allFinite()) return invalidArgument(where + ": covariance is not finite");
    if (centroid.covariance.diagonal().maxCoeff() > kMaxCentroidVarianceM2) {
      return invalidArgument(where + ": covariance has a variance above 1e8 m^2");
    }
    // Positive semi-definite, up to the float rounding of the wire.
    const Eigen::Vector3d values = symmetricEigenvalues(centroid.covariance).values;
    if (values(0) < -1e-6 * std::max(values(2), 1e-12)) {
      return invalidArgument(where + ": covariance is not positive semi-definite");
    }
    if (c.point_count() < 2) {
      return invalidArgument(where + ": point_count " + std::to_string(c.point_count()) +
                             ", a centroid summarises at least 2 points");
    }
    centroid.point_count = static_cast<std::size_t>(c.point_count());
    out.centroids.push_back(centroid);
  }
  return out;
}

v1::Track toProto(const tracking::Track& track) {
  v1::Track out;
  out.set_id(track.id);
  out.set_label(track.label);
  switch (track.state) {
    case tracking::TrackState::kTentative:
      out.set_state(v1::TRACK_STATE_TENTATIVE);
      break;
    case tracking::TrackState::kConfirmed:
      out.set_state(v1::TRACK_STATE_CONFIRMED);
      break;
    case tracking::TrackState::kLost:
      out.set_state(v1::TRACK_STATE_LOST);
      break;
  }
  out.set_x(track.position.x());
  out.set_y(track.position.y());
  out.set_vx(track.velocity.x());
  out.set_vy(track.velocity.y());
  out.add_covariance(track.covariance(0, 0));
  out.add_covariance(track.covariance(0, 1));
  out.add_covariance(track.covariance(1, 1));
  out.set_created_ns(track.created_ns);
  out.set_last_update_ns(track.last_update_ns);
  out.set_camera_confirmed(track.camera_confirmed);
  if (track.heading_rad) out.set_heading(*track.heading_rad);
  return out;
}

Expected<tracking::Track> fromProto(const v1::Track& track) {
  tracking::Track out;
  out.id = track.id();
  out.label = track.label();
  switch (track.state()) {
    case v1::TRACK_STATE_TENTATIVE:
      out.state = tracking::TrackState::kTentative;
      break;
    case v1::TRACK_STATE_CONFIRMED:
      out.state = tracking::TrackState::kConfirmed;
      break;
    case v1::TRACK_STATE_LOST:
      out.state = tracking::TrackState::kLost;
      break;
    default:
      return invalidArgument("track " + std::to_string(track.id()) + ": unknown state");
  }
  if (track.covariance_size() != 3) return invalidArgument("track " + std::to_string(track.id()) + ": covariance must be xx, xy, yy");
  for (const double v : {track.x(), track.y(), track.vx(), track.vy(), track.covariance(0), track.covariance(1), track.covariance(2)}) {
    if (!std::isfinite(v)) return invalidArgument("track " + std::to_string(track.id()) + ": position, velocity and covariance must be finite");
  }
  out.position = {track.x(), track.y()};
  out.velocity = {track.vx(), track.vy()};
  out.covariance << track.covariance(0), track.covariance(1), track.covariance(1), track.covariance(2);
  out.created_ns = track.created_ns();
  out.last_update_ns = track.last_update_ns();
  out.camera_confirmed = track.camera_confirmed();
  if (track.has_heading()) {
    if (!std::isfinite(track.heading()) || std::abs(track.heading()) > std::numbers::pi + 1e-9) {
      return invalidArgument("track " + std::to_string(track.id()) + ": heading must be finite radians in [-pi, pi]");
    }
    out.heading_rad = track.heading();
  }
  return out;
}

Expected<tracking::TrackSnapshot> fromProto(const v1::TrackList& list) {
  tracking::TrackSnapshot out;
  out.lidar_time_ns = list.lidar_time_ns();
  out.published_time_ns = list.published_time_ns();
  auto association = tracking::parseAssociation(list.association());
  if (!association) return invalidArgument("track list: association: " + association.error().message);
  out.association = *association;
  out.tracks.reserve(static_cast<std::size_t>(list.tracks_size()));
  for (const auto& proto : list.tracks()) {
    auto track = fromProto(proto);
    if (!track) return track.error();
    out.tracks.push_back(std::move(*track));
  }
  return out;
}

}  // namespace fogmap
