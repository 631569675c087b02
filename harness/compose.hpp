#pragma once
// A docker compose deployment and a Prometheus scrape configuration generated from a topology
// (docker/README.md): the same file that `fogctl up` runs as local processes runs as containers.
// Pure text generation, no Docker needed.
#include <filesystem>
#include <string>
#include <vector>

#include "common/base/status.hpp"
#include "common/config/topology.hpp"

namespace fogmap::harness {

// The user the fogmap image runs its services as (docker/Dockerfile); `fogctl certs --owner`
// gives it the private keys.
inline constexpr int kImageUid = 10001;

// The certificate the deployment's live view presents to the root and the tracker (with TLS): a
// client of its own, whose key `fogctl certs --owner` gives to the containers' user.
inline constexpr const char* kViewIdentity = "view";

struct ComposeOptions {
  // The topology file as the user named it, and the directory of the compose file: the directory
  // is mounted read-only at /fogmap in every container, so the topology and every file it names
  // (scans, certificates) must lie inside it.
  std::filesystem::path topology_file;
  std::filesystem::path project_dir;
  // The scrape configuration Prometheus reads, relative to project_dir (see prometheusConfig).
  std::filesystem::path prometheus_config;
  std::string image = "fogmap:latest";
  std::string prometheus_image = "fogmap-prometheus:latest";
  std::string grafana_image = "grafana/grafana-oss:10.4.2";
  std::string prometheus_listen = "127.0.0.1:9090";
  std::string grafana_listen = "127.0.0.1:3000";
  std::string view_listen = "127.0.0.1:8088";  // fogctl view's page (the `view` service)
  std::string command;  // the command line that generated it, written in the header
};

// The compose file (valid for Compose v2 and Debian's docker-compose 1.29): one service per node
// (named after it, its binary from serviceName(role): edges, aggregators, detection nodes and
// trackers alike; host networking, so it listens on the address its topology entry gives; a V4L2
// camera's device passed in), the live view (`fogctl view`, listening on view_listen only; with TLS
// it presents the operator's certificate), Prometheus, and Grafana in the `grafana` profile. Errors name what
// cannot be deployed: a file outside project_dir (scans, scenes, camera frames, detector models,
// TLS files), a path that is empty or cannot be resolved, a node named like an infrastructure
// service. It checks no more than that: `fogctl compose` runs checkStartable (launcher.hpp) first.
Expected<std::string> composeFile(const TopologyConfig& topology, const ComposeOptions& options);

struct PrometheusOptions {
  std::vector<std::string> rule_files;  // as Prometheus sees them
  std::string scrape_interval = "5s";
  std::string evaluation_interval = "5s";
  std::string command;  // the command line that generated it, written in the header
};

// A Prometheus configuration scraping every node's /metrics (job `fogmap`, instance = node name).
std::string prometheusConfig(const TopologyConfig& topology, const PrometheusOptions& options);

}  // namespace fogmap::harness
