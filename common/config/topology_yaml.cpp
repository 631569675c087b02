#include "common/config/topology_yaml.hpp"

#include <yaml-cpp/yaml.h>

#include "common/config/camera_node.hpp"
#include "common/config/displacement_node.hpp"
#include "common/config/tracker_node.hpp"
#include "common/config/yaml_fields.hpp"

namespace fogmap {

std::string toYaml(const TopologyConfig& t) {
  YAML::Emitter out;
  out.SetDoublePrecision(12);  // 0.35, not 0.34999999999999998
  out << YAML::BeginMap;
  out << YAML::Key << "name" << YAML::Value << t.name;
  out << YAML::Key << "mode" << YAML::Value << modeName(t.mode);
  if (t.baseline_ships_raw) out << YAML::Key << "baseline_ships" << YAML::Value << "raw";
  out << YAML::Key << "deadline_ms" << YAML::Value << t.deadline_ms;
  out << YAML::Key << "period_ms" << YAML::Value << t.period_ms;
  out << YAML::Key << "max_message_bytes" << YAML::Value << t.max_message_bytes;
  out << YAML::Key << "max_scan_bytes" << YAML::Value << t.max_scan_bytes;
  const AdmissionLimits& a = t.admission;
  out << YAML::Key << "admission" << YAML::Value << YAML::BeginMap << YAML::Key << "window_periods" << YAML::Value
      << a.window_periods << YAML::Key << "world_extent_m" << YAML::Value << a.world_extent_m << YAML::Key
      << "max_ellipsoids_per_map" << YAML::Value << a.max_ellipsoids_per_map << YAML::Key << "max_map_bytes"
      << YAML::Value << a.max_map_bytes << YAML::Key << "min_eigenvalue_m2" << YAML::Value << a.min_eigenvalue_m2
      << YAML::Key << "max_eigenvalue_m2" << YAML::Value << a.max_eigenvalue_m2 << YAML::Key << "max_condition"
      << YAML::Value << a.max_condition << YAML::Key << "max_subscribers" << YAML::Value << a.max_subscribers
      << YAML::EndMap;
  out << YAML::Key << "madc" << YAML::Value << YAML::BeginMap << YAML::Key << "eps_m" << YAML::Value << t.madc.clustering.eps_m
      << YAML::Key << "min_points" << YAML::Value << t.madc.clustering.min_points;
  if (t.madc.fragment_min_points) out << YAML::Key << "fragment_min_points" << YAML::Value << *t.madc.fragment_min_points;
  out << YAML::Key << "alpha" << YAML::Value << t.madc.alpha;
  if (t.madc.alpha_max > 0.0) out << YAML::Key << "alpha_max" << YAML::Value << t.madc.alpha_max;
  out << YAML::Key << "threads" << YAML::Value << t.madc.clustering.threads << YAML::EndMap;
  if (t.objects.boxes) {
    out << YAML::Key << "objects" << YAML::Value << YAML::BeginMap << YAML::Key << "boxes" << YAML::Value << true;
    if (t.objects.classifier) out << YAML::Key << "classifier" << YAML::Value << t.objects.classifier->string();
    out << YAML::EndMap;
  }
  out << YAML::Key << "preprocess" << YAML::Value << YAML::BeginMap;
  auto list3 = [&](const Eigen::Vector3d& v) {
    out << YAML::Flow << YAML::BeginSeq << v.x() << v.y() << v.z() << YAML::EndSeq;
  };
  if (t.preprocess.crop) {
    out << YAML::Key << "crop" << YAML::Value << YAML::BeginMap << YAML::Key << "min_m" << YAML::Value;
    list3(t.preprocess.crop->min_m);
    out << YAML::Key << "max_m" << YAML::Value;
    list3(t.preprocess.crop->max_m);
    out << YAML::EndMap;
  }
  if (t.preprocess.voxel_leaf_m) out << YAML::Key << "voxel_leaf_m" << YAML::Value << *t.preprocess.voxel_leaf_m;
  if (t.preprocess.ground) {
    out << YAML::Key << "ground" << YAML::Value << YAML::BeginMap << YAML::Key << "distance_threshold_m" << YAML::Value
        << t.preprocess.ground->distance_threshold_m << YAML::Key << "max_tilt_deg" << YAML::Value
        << t.preprocess.ground->max_tilt_deg;
    if (t.preprocess.ground->ground_z_hint_m) {
      out << YAML::Key << "ground_z_hint_m" << YAML::Value << *t.preprocess.ground->ground_z_hint_m;
    }
    out << YAML::EndMap;
  }
  out << YAML::EndMap;
  if (t.tls) {
    out << YAML::Key << "tls" << YAML::Value << YAML::BeginMap << YAML::Key << "ca" << YAML::Value << t.tls->ca.string();
    // Left to its default when it is the CA's directory (which may be "", not a valid value).
    if (t.tls->cert_dir != t.tls->ca.parent_path()) {
      out << YAML::Key << "cert_dir" << YAML::Value << t.tls->cert_dir.string();
    }
    out << YAML::Key << "geofence_clients" << YAML::Value << YAML::Flow << t.tls->geofence_clients << YAML::EndMap;
  }
  out << YAML::Key << "nodes" << YAML::Value << YAML::BeginSeq;
  for (const auto& n : t.nodes) {
    out << YAML::BeginMap;
    out << YAML::Key << "name" << YAML::Value << n.name;
    out << YAML::Key << "id" << YAML::Value << n.id;
    out << YAML::Key << "role" << YAML::Value << roleName(n.role);
    if (!n.parent.empty()) out << YAML::Key << "parent" << YAML::Value << n.parent;
    out << YAML::Key << "host" << YAML::Value << n.host;
    if (n.port != 0) out << YAML::Key << "port" << YAML::Value << n.port;
    out << YAML::Key << "metrics_port" << YAML::Value << n.metrics_port;
    if (n.sensor) {
      const auto& s = *n.sensor;
      out << YAML::Key << "sensor" << YAML::Value << YAML::BeginMap;
      out << YAML::Key << "source" << YAML::Value << s.source.string();
      if (s.simulated()) {
        out << YAML::Key << "scene" << YAML::Value << s.scene.string();
        out << YAML::Key << "lidar" << YAML::Value << s.lidar;
      }
      out << YAML::Key << "rate_hz" << YAML::Value << s.rate_hz;
      out << YAML::Key << "loop" << YAML::Value << s.loop;
      if (s.frames) out << YAML::Key << "frames" << YAML::Value << *s.frames;
      if (s.split) {
        out << YAML::Key << "split" << YAML::Value << YAML::Flow << YAML::BeginMap << YAML::Key << "views" << YAML::Value
            << s.split->views << YAML::Key << "index" << YAML::Value << s.split->index << YAML::Key << "overlap_deg"
            << YAML::Value << s.split->overlap_deg << YAML::EndMap;
      }
      if (!s.pose.isApprox(Eigen::Isometry3d::Identity())) {
        out << YAML::Key << "pose" << YAML::Value << YAML::BeginMap << YAML::Key << "translation_m" << YAML::Value;
        list3(s.pose.translation());
        out << YAML::Key << "rpy_deg" << YAML::Value;
        list3(rpyDegrees(s.pose.rotation()));
        out << YAML::EndMap;
      }
      if (s.clustering != ClusteringMode::kExact) {
        out << YAML::Key << "clustering" << YAML::Value << clusteringModeName(s.clustering);
        out << YAML::Key << "model" << YAML::Value << s.model;
      }
      out << YAML::EndMap;
    }
    if (n.displacement) {
      const auto& d = *n.displacement;
      out << YAML::Key << "displacement" << YAML::Value << YAML::BeginMap << YAML::Key << "tracker" << YAML::Value
          << d.tracker << YAML::Key << "voxel_m" << YAML::Value << d.params.voxel_m << YAML::Key << "neighbour_m"
          << YAML::Value << d.params.neighbour_m << YAML::Key << "min_neighbours" << YAML::Value << d.params.min_neighbours
          << YAML::Key << "min_points" << YAML::Value << d.params.min_points << YAML::Key << "min_z_variance_m2"
          << YAML::Value << d.params.min_z_variance_m2 << YAML::EndMap;
    }
    if (n.camera) {
      const auto& c = *n.camera;
      out << YAML::Key << "camera" << YAML::Value << YAML::BeginMap;
      out << YAML::Key << "source" << YAML::Value << c.source.string();
      if (c.simulated()) {
        out << YAML::Key << "scene" << YAML::Value << c.scene.string();
        out << YAML::Key << "camera" << YAML::Value << c.camera;
      }
      out << YAML::Key << "rate_hz" << YAML::Value << c.rate_hz;
      out << YAML::Key << "loop" << YAML::Value << c.loop;
      if (c.frames) out << YAML::Key << "frames" << YAML::Value << *c.frames;
      out << YAML::Key << "queue_frames" << YAML::Value << c.queue_frames;
      if (c.max_image_pixels != camera::kDefaultMaxImagePixels) {
        out << YAML::Key << "max_image_pixels" << YAML::Value << c.max_image_pixels;
      }
      out << YAML::Key << "detector" << YAML::Value << YAML::BeginMap;
      if (c.truth) {
        out << YAML::Key << "kind" << YAML::Value << "truth";
        out << YAML::Key << "truth" << YAML::Value << YAML::Flow << YAML::BeginMap << YAML::Key << "miss_rate" << YAML::Value
            << c.truth_replay.miss_rate << YAML::Key << "box_jitter_px" << YAML::Value << c.truth_replay.box_jitter_px
            << YAML::Key << "latency_ms" << YAML::Value << c.truth_replay.latency_ms << YAML::EndMap;
      } else {
        const auto& d = c.detector;
        out << YAML::Key << "kind" << YAML::Value << camera::detectorKindName(d.kind);
        switch (d.kind) {
          case camera::DetectorKind::kHog:
            out << YAML::Key << "hog" << YAML::Value << YAML::Flow << YAML::BeginMap << YAML::Key << "hit_threshold"
                << YAML::Value << d.hog.hit_threshold << YAML::Key << "scale" << YAML::Value << d.hog.scale << YAML::Key
                << "win_stride_px" << YAML::Value << d.hog.win_stride_px << YAML::Key << "upscale" << YAML::Value
                << d.hog.upscale << YAML::Key << "min_height_px" << YAML::Value << d.hog.min_height_px << YAML::Key
                << "nms_iou" << YAML::Value << d.hog.nms_iou << YAML::EndMap;
            break;
          case camera::DetectorKind::kCascade:
            out << YAML::Key << "cascade" << YAML::Value << YAML::BeginMap << YAML::Key << "cascade_path" << YAML::Value
                << d.cascade.cascade_path << YAML::Key << "label" << YAML::Value << d.cascade.label << YAML::Key
                << "scale_factor" << YAML::Value << d.cascade.scale_factor << YAML::Key << "min_neighbors" << YAML::Value
                << d.cascade.min_neighbors << YAML::Key << "min_size_px" << YAML::Value << d.cascade.min_size_px
                << YAML::Key << "nms_iou" << YAML::Value << d.cascade.nms_iou << YAML::EndMap;
            break;
          case camera::DetectorKind::kDnn:
            out << YAML::Key << "dnn" << YAML::Value << YAML::BeginMap << YAML::Key << "model_path" << YAML::Value
                << d.dnn.model_path;
            if (!d.dnn.config_path.empty()) out << YAML::Key << "config_path" << YAML::Value << d.dnn.config_path;
            out << YAML::Key << "names_path" << YAML::Value << d.dnn.names_path << YAML::Key << "output" << YAML::Value
                << camera::dnnOutputName(d.dnn.output) << YAML::Key << "input_width" << YAML::Value << d.dnn.input_width
                << YAML::Key << "input_height" << YAML::Value << d.dnn.input_height << YAML::Key << "mean" << YAML::Value;
            list3(Eigen::Vector3d(d.dnn.mean[0], d.dnn.mean[1], d.dnn.mean[2]));
            out << YAML::Key << "scale" << YAML::Value << d.dnn.scale << YAML::Key << "swap_rb" << YAML::Value
                << d.dnn.swap_rb << YAML::Key << "confidence_threshold" << YAML::Value << d.dnn.confidence_threshold
                << YAML::Key << "nms_threshold" << YAML::Value << d.dnn.nms_threshold << YAML::EndMap;
            break;
        }
      }
      out << YAML::EndMap;
      const auto& k = c.calibration;
      out << YAML::Key << "calibration" << YAML::Value << YAML::BeginMap << YAML::Key << "fx" << YAML::Value << k.fx
          << YAML::Key << "fy" << YAML::Value << k.fy << YAML::Key << "cx" << YAML::Value << k.cx << YAML::Key << "cy"
          << YAML::Value << k.cy << YAML::Key << "width" << YAML::Value << k.width << YAML::Key << "height" << YAML::Value
          << k.height;
      if (!k.distortion.none()) {
        out << YAML::Key << "distortion" << YAML::Value << YAML::Flow << YAML::BeginSeq << k.distortion.k1
            << k.distortion.k2 << k.distortion.p1 << k.distortion.p2 << k.distortion.k3 << YAML::EndSeq;
      }
      const Eigen::Isometry3d pose = k.world_to_camera.inverse();
      out << YAML::Key << "pose" << YAML::Value << YAML::BeginMap << YAML::Key << "translation_m" << YAML::Value;
      list3(pose.translation());
      out << YAML::Key << "rpy_deg" << YAML::Value;
      list3(rpyDegrees(pose.rotation()));
      out << YAML::EndMap << YAML::EndMap;
      out << YAML::EndMap;
    }
    if (n.tracker) {
      const auto& c = n.tracker->tracking;
      out << YAML::Key << "tracker" << YAML::Value << YAML::BeginMap;
      if (n.tracker->input == TrackerInput::kCentroids) {
        out << YAML::Key << "input" << YAML::Value << trackerInputName(n.tracker->input) << YAML::Key << "centroid_merge_m"
            << YAML::Value << n.tracker->centroid_merge_m << YAML::Key << "visible_side_max_radius_m" << YAML::Value
            << n.tracker->visible_side_max_radius_m;
      }
      out << YAML::Key << "association" << YAML::Value
          << tracking::associationName(c.association) << YAML::Key << "eps_sync_s" << YAML::Value << c.eps_sync_s
          << YAML::Key << "rho_overlay_m" << YAML::Value << c.rho_overlay_m << YAML::Key << "rho_purecloud_m" << YAML::Value
          << c.rho_purecloud_m << YAML::Key << "gate_chi2" << YAML::Value << c.gate_chi2 << YAML::Key
          << "acceleration_sigma" << YAML::Value << c.acceleration_sigma << YAML::Key << "initial_speed_sigma"
          << YAML::Value << c.initial_speed_sigma << YAML::Key << "min_measurement_sigma_m" << YAML::Value
          << c.min_measurement_sigma_m << YAML::Key << "confirm_hits" << YAML::Value << c.confirm_hits << YAML::Key
          << "tentative_timeout_s" << YAML::Value << c.tentative_timeout_s << YAML::Key << "track_timeout_s"
          << YAML::Value << c.track_timeout_s << YAML::Key << "publish_lost_s" << YAML::Value << c.publish_lost_s
          << YAML::Key << "max_buffered_frames" << YAML::Value
          << c.max_buffered_frames << YAML::Key << "max_detection_wait_s" << YAML::Value << c.max_detection_wait_s
          << YAML::Key << "lidar_class_weight" << YAML::Value << c.lidar_class_weight << YAML::EndMap;
    }
    if (n.tls) {
      out << YAML::Key << "tls" << YAML::Value << YAML::BeginMap << YAML::Key << "cert" << YAML::Value
          << n.tls->cert.string() << YAML::Key << "key" << YAML::Value << n.tls->key.string() << YAML::EndMap;
    }
    out << YAML::EndMap;
  }
  out << YAML::EndSeq << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

}  // namespace fogmap
