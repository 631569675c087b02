#pragma once
// One merge-aggregator process as its topology node says: the core behind its lock, the link to its
// parent (an intermediate), the ingest adapter, the global-map adapter (the root), and the emitter
// between them; and how it serves and stops (serveUntilStopped):
//   serving:           the emitter polls
//   stop accepting:    no upload is taken any more (unanswered ones are re-sent to the restarted node)
//   drain:             the emitter stops, then emits every open epoch
//   end subscriptions: subscribers read what was published (the root)
//   flush:             the parent answers what is left (an intermediate); what is not is logged
#include <memory>
#include <optional>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "common/base/status.hpp"
#include "services/common/parent_link.hpp"
#include "services/common/service_main.hpp"
#include "services/merge_aggregator/aggregator_runtime.hpp"
#include "services/merge_aggregator/global_map_service.hpp"
#include "services/merge_aggregator/ingest_service.hpp"

namespace fogmap {

class AggregatorProcess {
 public:
  // Builds everything from `context` (which must outlive it); an error when the topology gives the
  // node no valid aggregator configuration.
  static Expected<std::unique_ptr<AggregatorProcess>> create(const ServiceContext& context);
  AggregatorProcess(const AggregatorProcess&) = delete;
  AggregatorProcess& operator=(const AggregatorProcess&) = delete;

  std::vector<grpc::Service*> services();
  ServiceLifecycle lifecycle();

  bool isRoot() const { return is_root_; }

 private:
  AggregatorProcess(const ServiceContext& context, MergeAggregator core);
  EmitterSinks emitterSinks();

  const ServiceContext& context_;
  const bool is_root_;
  SharedAggregator aggregator_;
  std::unique_ptr<ParentLink> parent_link_;  // an intermediate's
  IngestService ingest_;
  std::optional<GlobalMapService> global_maps_;  // the root's
  Emitter emitter_;  // after everything it feeds: stopped and destroyed first
};

}  // namespace fogmap
