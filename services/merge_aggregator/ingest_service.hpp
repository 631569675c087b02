#pragma once
// gRPC adapter for MapIngest.Push: the children's long-lived upload streams. Converts each Upload
// (fromProto), hands it to the core, acknowledges it, and relays point chunks at an intermediate.
//
// Child identity: a stream belongs to the direct child resolved from the header.node of its first
// well-formed Upload: the child itself (its own maps, or an edge child's chunks), or, for a chunk
// relayed by an intermediate child, the sensor's id, which the core maps to the child whose
// subtree holds that sensor. The child is live while at least one of its streams is open; a
// sender that resolves to no child ends the stream with INVALID_ARGUMENT (a topology mismatch).
//
// Malformed uploads (fromProto fails, or the core rejects them): counted, not acknowledged, and
// the stream stays open, so one bad message never costs the accepted ones. Accepted and late
// uploads are acknowledged with their sequence.
#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <string>

#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/metrics.hpp"
#include "services/merge_aggregator/aggregator_runtime.hpp"

namespace fogmap {

struct IngestCounters {
  std::uint64_t accepted = 0;   // maps and chunks taken into an open epoch (or relayed)
  std::uint64_t late = 0;       // acknowledged but discarded: their epoch was already emitted
  std::uint64_t malformed = 0;  // not acknowledged
  std::uint64_t rejected_streams = 0;  // streams from a sender that is no child of this node
};

class IngestService final : public v1::MapIngest::Service {
 public:
  // `relay` forwards point chunks to the parent (intermediates; empty at the root). `metrics` may
  // be null.
  IngestService(SharedAggregator& aggregator, Metrics* metrics, std::function<void(v1::Upload)> relay,
                NowNs now_ns = systemNowNs);

  grpc::Status Push(grpc::ServerContext* context, grpc::ServerReaderWriter<v1::Ack, v1::Upload>* stream) override;

  IngestCounters counters() const;
  // Called after every accepted map or chunk, so the emitter can publish a completed epoch at
  // once instead of at its next poll. Set before the server starts.
  void onArrival(std::function<void()> callback) { on_arrival_ = std::move(callback); }
  // Names for the `peer` label of the byte counters (child id -> node name), so that they match the
  // sender's own label; unnamed children are labelled by id. Set before the server starts.
  void peerNames(std::map<std::uint32_t, std::string> names) { peer_names_ = std::move(names); }

 private:
  // Hand one converted upload to the core; true when it is to be acknowledged.
  bool handleMap(const MapMessage& map);
  std::function<void()> on_arrival_;
  std::map<std::uint32_t, std::string> peer_names_;
  bool handlePoints(PointChunk chunk);
  void countMalformed(const std::string& what);

  SharedAggregator& aggregator_;
  Metrics* metrics_;
  std::function<void(v1::Upload)> relay_;
  NowNs now_ns_;
  std::atomic<std::uint64_t> accepted_{0};
  std::atomic<std::uint64_t> late_{0};
  std::atomic<std::uint64_t> malformed_{0};
  std::atomic<std::uint64_t> rejected_streams_{0};
};

}  // namespace fogmap
