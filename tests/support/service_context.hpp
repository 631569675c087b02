#pragma once
// A service's start-up done by hand, for running a service's process in the test's own process:
// node `name` of `topology` (plaintext, /metrics not served), with a stop the test requests.
#include <filesystem>
#include <map>
#include <optional>
#include <string>

#include "services/common/service_main.hpp"

namespace fogmap::test_support {

class HandMadeContext {
 public:
  HandMadeContext(TopologyConfig topology, const std::string& name)
      : topology_(std::move(topology)),
        node_(*topology_.find(name)),
        spec_{node_.role, ""},
        metrics_("", serviceName(node_.role), name) {}
  HandMadeContext(const HandMadeContext&) = delete;
  HandMadeContext& operator=(const HandMadeContext&) = delete;

  const ServiceContext& context() const { return context_; }
  StopRequest& stop() { return stop_; }
  Metrics& metrics() { return metrics_; }
  const NodeConfig& node() const { return node_; }

 private:
  TopologyConfig topology_;
  const NodeConfig& node_;
  ServiceSpec spec_;
  std::filesystem::path file_ = "topology.yaml";
  std::optional<TlsPem> tls_;
  std::map<std::string, std::string> flags_;
  StopRequest stop_;
  Metrics metrics_;
  ServiceContext context_{spec_, file_, topology_, node_, tls_, flags_, stop_, metrics_};
};

}  // namespace fogmap::test_support
