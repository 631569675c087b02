#pragma once
// Reading a topology file: parsed and validated once, at start, with errors that name the place in
// the file ("topology: nodes[3].sensor.rate_hz: must be in (0, 1000]").
#include <filesystem>
#include <string>

#include "common/base/status.hpp"
#include "common/config/topology.hpp"

namespace fogmap {

// Parses and validates (names of letters, digits, '.', '_', '-'; unique names, ids and ports;
// exactly one root; parents exist and are aggregators; no cycles; edges have sensors). Relative
// sensor paths (source, scene) resolve against `base_dir`. A sensor is recorded scans
// (`source: DIR|FILE`, optionally `split`) or a simulated LiDAR (`source: sim, scene: FILE, lidar:
// NAME`): `scene` and `lidar` are required with source sim and refused otherwise, `split` is refused
// with it.
// Hosts must be IPv4 addresses; madc and admission values are checked by common/config/admission.hpp.
// The optional tls section: `ca` is required, `cert_dir` and `geofence_clients` optional; a node's
// `tls: {cert, key}` needs both keys and the top-level section. TLS files are read when a service
// starts, not here. An edge's `displacement:` names a tracker whose input is centroids, and such a
// tracker has at least one edge sending to it.
Expected<TopologyConfig> parseTopology(const std::string& yaml_text, const std::filesystem::path& base_dir);
Expected<TopologyConfig> loadTopology(const std::filesystem::path& path);

}  // namespace fogmap
