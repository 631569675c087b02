#pragma once
// gRPC adapter for MapIngest.Push: the children's long-lived upload streams. Converts each Upload
// (fromProto), hands it to the core, and answers it (docs/design.md "Delivery"):
//   APPLIED  merged into an open epoch, or (a relayed chunk) answered APPLIED by the next hop;
//   LATE     merged into an already emitted epoch, which is published again as a late revision;
//   REFUSED  not applied, with the reason and a gRPC code (INVALID_ARGUMENT for a broken rule,
//            RESOURCE_EXHAUSTED for a bound); the child never re-sends it.
// Every upload is answered exactly once, except when this node stops: then the stream ends
// UNAVAILABLE and the child re-sends what was not answered to the restarted node.
//
// Child identity: a stream belongs to the direct child resolved from the header.node of its first
// well-formed Upload (the child itself, or for a chunk relayed by an intermediate child, the
// sensor's id, which the core maps to that child); every later upload must speak for that child.
// A sender that resolves to no child has that upload answered REFUSED (unknown_node) and the
// stream ended with INVALID_ARGUMENT.
// With TLS (identifyPeersByCertificate) the child is the one named by the stream's verified client
// certificate instead, fixed before any upload is read; the same rule then holds for every upload
// (forged_node). A certificate that names no child gets every upload on its stream answered
// REFUSED as unknown_peer (counted, never applied) while the stream stays open, so the peer learns
// why, and never reconnects in a loop as an ended stream would make it.
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>

#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/metrics.hpp"
#include "services/merge_aggregator/aggregator_runtime.hpp"

namespace fogmap {

// Called once with the next hop's answer to a relayed upload (nullopt: dropped or abandoned).
using RelaySettled = std::function<void(const std::optional<v1::Ack>& answer)>;
using Relay = std::function<void(v1::Upload upload, RelaySettled settled)>;

class IngestService final : public v1::MapIngest::Service {
 public:
  // `relay` forwards point chunks to the parent (intermediates; empty at the root). `metrics` may
  // be null.
  IngestService(SharedAggregator& aggregator, Metrics* metrics, Relay relay, NowNs now_ns = systemNowNs);

  grpc::Status Push(grpc::ServerContext* context, grpc::ServerReaderWriter<v1::Ack, v1::Upload>* stream) override;

  // Called after every accepted map or chunk, so the emitter can publish a completed epoch at
  // once instead of at its next poll. Set before the server starts.
  void onArrival(std::function<void()> callback) { on_arrival_ = std::move(callback); }
  // Names for the `peer` label of the byte counters (child id -> node name), so that they match the
  // sender's own label; unnamed children are labelled by id. Set before the server starts.
  void peerNames(std::map<std::uint32_t, std::string> names) { peer_names_ = std::move(names); }
  // The server requires client certificates (TLS): a stream's child is the one its certificate
  // names. Set before the server starts.
  void identifyPeersByCertificate() { by_certificate_ = true; }
  // From now on no upload is taken: open streams end UNAVAILABLE without answering what they
  // read, so nothing is acknowledged that the drain before shutdown would not emit.
  void stopAccepting() { stopping_ = true; }

 private:
  struct AckWriter;
  // Hands one upload to the core and answers it (now, or when the next hop answers a relay);
  // false when this node stopped taking uploads (nothing was applied or answered).
  bool handle(const v1::Upload& upload, std::uint32_t child, const std::shared_ptr<AckWriter>& writer);

  SharedAggregator& aggregator_;
  Metrics* metrics_;
  Relay relay_;
  NowNs now_ns_;
  std::size_t max_map_bytes_;  // admission bound, checked before an upload is converted
  std::function<void()> on_arrival_;
  std::map<std::uint32_t, std::string> peer_names_;
  bool by_certificate_ = false;
  std::atomic<bool> stopping_{false};
};

}  // namespace fogmap
