#include "services/merge_aggregator/ingest_service.hpp"

#include <mutex>
#include <utility>

#include "services/common/grpc_options.hpp"
#include "services/common/proto_convert.hpp"

namespace fogmap {
namespace {

const char* kindOf(const v1::Upload& upload) {
  return upload.payload_case() == v1::Upload::kPoints ? "points" : "map";
}

// The sender named by an upload's header, before conversion (to resolve the stream's child).
std::optional<std::uint32_t> senderOf(const v1::Upload& upload) {
  if (upload.payload_case() == v1::Upload::kMap && upload.map().has_header()) return upload.map().header().node();
  if (upload.payload_case() == v1::Upload::kPoints && upload.points().has_header()) {
    return upload.points().header().node();
  }
  return std::nullopt;
}

// Identifies the content of an upload, whatever its sequence: a re-sent copy has the same.
std::uint64_t fingerprintOf(const v1::Upload& upload) {
  std::string bytes;
  if (upload.payload_case() == v1::Upload::kMap) {
    upload.map().SerializeToString(&bytes);
  } else if (upload.payload_case() == v1::Upload::kPoints) {
    upload.points().SerializeToString(&bytes);
  }
  return std::hash<std::string>{}(bytes);
}

grpc::Status stoppedStatus() {
  return {grpc::StatusCode::UNAVAILABLE, "the aggregator is shutting down; re-send later"};
}

}  // namespace

// Answers on one stream, from its handler and from relay callbacks; writes are serialised and
// stop once the handler has returned (the stream object is gone then).
struct IngestService::AckWriter {
  std::mutex mutex;
  grpc::ServerReaderWriter<v1::Ack, v1::Upload>* stream = nullptr;

  bool write(const v1::Ack& ack) {
    std::lock_guard lock(mutex);
    return stream != nullptr && stream->Write(ack);
  }
  void close() {
    std::lock_guard lock(mutex);
    stream = nullptr;
  }
};

IngestService::IngestService(SharedAggregator& aggregator, Metrics* metrics, Relay relay, NowNs now_ns)
    : aggregator_(aggregator),
      metrics_(metrics),
      relay_(std::move(relay)),
      now_ns_(std::move(now_ns)),
      // The configuration is fixed once the core exists: read the bound once, not per upload.
      max_map_bytes_(aggregator.with([](MergeAggregator& core) { return core.config().admission.max_map_bytes; })) {}

grpc::Status IngestService::Push(grpc::ServerContext* context,
                                 grpc::ServerReaderWriter<v1::Ack, v1::Upload>* stream) {
  std::optional<std::uint32_t> child;
  std::string peer = "unknown";  // until the first upload (or the certificate) names the child
  std::optional<std::string> unknown_peer;  // TLS: why every upload of this stream is refused
  if (by_certificate_) {
    const std::optional<std::string> name = peerCertificateName(*context);
    child = aggregator_.with([&](MergeAggregator& core) { return core.peerConnected(name.value_or("")); });
    if (child) {
      const auto known = peer_names_.find(*child);
      peer = known != peer_names_.end() ? known->second : std::to_string(*child);
    } else {
      // The reason's name leads: the peer's log shows which rule refused it.
      unknown_peer = std::string(refusalName(Refusal::kUnknownPeer)) + ": " +
                     (name ? "the client certificate names '" + *name + "', which is not a child of this aggregator"
                           : std::string("the client certificate names no single peer"));
    }
  }
  const auto writer = std::make_shared<AckWriter>();
  writer->stream = stream;
  // The child stays live as long as this stream (and a grace after), however the handler ends.
  struct Disconnect {
    IngestService& service;
    const std::optional<std::uint32_t>& child;
    const std::shared_ptr<AckWriter>& writer;
    ~Disconnect() {
      writer->close();
      if (child) {
        service.aggregator_.with(
            [this](MergeAggregator& core) { core.childDisconnected(*child, service.now_ns_()); });
      }
    }
  } disconnect{*this, child, writer};

  v1::Upload upload;
  while (stream->Read(&upload)) {
    if (stopping_) return stoppedStatus();
    if (unknown_peer) {
      // Read, counted and answered, never converted.
      if (metrics_ != nullptr) metrics_->bytesReceived(peer, kindOf(upload), upload.ByteSizeLong());
      const Refused refused =
          aggregator_.with([&](MergeAggregator& core) { return core.refuse(Refusal::kUnknownPeer, *unknown_peer); });
      if (!writer->write(refusedAck(upload.sequence(), refused))) break;
      continue;
    }
    if (!child) {
      const auto sender = senderOf(upload);
      if (!sender) {
        if (metrics_ != nullptr) metrics_->bytesReceived(peer, kindOf(upload), upload.ByteSizeLong());
        const Refused refused = aggregator_.with([&](MergeAggregator& core) {
          return core.refuse(Refusal::kMalformed, "an upload without a header cannot name its sender");
        });
        if (!writer->write(refusedAck(upload.sequence(), refused))) break;
        continue;
      }
      auto connected = aggregator_.with([&](MergeAggregator& core) { return core.childConnected(*sender); });
      if (!connected) {
        // Answered like every upload (the sender settles it and does not re-send it), then the
        // stream ends: it can speak for no child.
        writer->write(refusedAck(upload.sequence(), Refused{Refusal::kUnknownNode, connected.error().message}));
        return toGrpcStatus(connected.error());
      }
      child = *connected;
      const auto name = peer_names_.find(*child);
      peer = name != peer_names_.end() ? name->second : std::to_string(*child);
    }
    if (metrics_ != nullptr) metrics_->bytesReceived(peer, kindOf(upload), upload.ByteSizeLong());
    if (!handle(upload, *child, writer)) return stoppedStatus();
  }
  return grpc::Status::OK;
}

bool IngestService::handle(const v1::Upload& upload, std::uint32_t child, const std::shared_ptr<AckWriter>& writer) {
  const std::size_t bytes = upload.ByteSizeLong();
  const UploadKey key{upload.sequence(), fingerprintOf(upload)};
  // Every call into the core looks at stopping_ under the core's lock: once Emitter::drain has
  // taken the lock (after stopAccepting), nothing more is applied, so every upload answered
  // APPLIED was merged before the drain emitted its epoch.
  const auto inCore = [&](auto&& f) {
    return aggregator_.with([&](MergeAggregator& core) -> std::optional<Outcome> {
      if (stopping_) return std::nullopt;
      return f(core);
    });
  };
  const auto refused = [&](Refusal reason, const std::string& message) {
    return inCore([&](MergeAggregator& core) {
      Outcome outcome;
      outcome.refused = core.refuse(reason, message);
      return outcome;
    });
  };
  std::optional<Outcome> outcome;
  std::size_t points = 0;
  if (bytes > max_map_bytes_) {
    // Refused before it is converted: a huge message must not cost the conversion either.
    outcome = refused(Refusal::kTooLarge, std::string(kindOf(upload)) + " upload of " + std::to_string(bytes) +
                                              " bytes, more than the bound of " + std::to_string(max_map_bytes_) +
                                              " (admission max_map_bytes)");
  } else if (upload.payload_case() == v1::Upload::kMap) {
    auto map = fromProto(upload.map());
    outcome = !map ? refused(Refusal::kMalformed, map.error().message)
                   : inCore([&](MergeAggregator& core) { return core.onMap(child, key, *map, bytes, now_ns_()); });
  } else if (upload.payload_case() == v1::Upload::kPoints) {
    auto chunk = fromProto(upload.points());
    if (chunk) points = chunk->points.size();
    outcome = !chunk ? refused(Refusal::kMalformed, chunk.error().message)
                     : inCore([&](MergeAggregator& core) {
                         return core.onPoints(child, key, std::move(*chunk), bytes, now_ns_());
                       });
  } else {
    outcome = refused(Refusal::kMalformed, "an upload without a payload");
  }
  if (!outcome) return false;

  if (!outcome->ok()) {
    writer->write(refusedAck(upload.sequence(), *outcome->refused));
    return true;
  }
  if (points > 0 && metrics_ != nullptr) metrics_->pointsIn(points);
  if (on_arrival_) on_arrival_();
  if (outcome->arrival != Arrival::kRelay) {
    writer->write(appliedAck(upload.sequence(), outcome->arrival == Arrival::kLate));
    return true;
  }
  if (!relay_) {
    const Error no_parent{ErrorCode::kInternal, "this aggregator has no parent to relay to"};
    writer->write(refusedAck(upload.sequence(), no_parent));
    return true;
  }
  // Relayed outside the core's lock; the child is answered when the next hop answers, with its
  // answer (status, reason and code), so an APPLIED answer always means the data reached the root
  // (or was applied on the way).
  v1::Upload relayed;
  *relayed.mutable_points() = toProto(*outcome->relay);
  if (metrics_ != nullptr) metrics_->pointsOut(points);
  relay_(std::move(relayed), [writer, sequence = upload.sequence()](const std::optional<v1::Ack>& answer) {
    if (answer) {
      v1::Ack ack = *answer;
      ack.set_sequence(sequence);
      writer->write(ack);
    } else {
      writer->write(refusedAck(sequence, resourceExhausted("dropped by the relay's full send queue")));
    }
  });
  return true;
}

}  // namespace fogmap
