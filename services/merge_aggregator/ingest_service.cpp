#include "services/merge_aggregator/ingest_service.hpp"

#include <optional>
#include <utility>

#include "services/common/grpc_options.hpp"
#include "services/common/proto_convert.hpp"

namespace fogmap {
namespace {

const char* kindOf(const v1::Upload& upload) {
  return upload.payload_case() == v1::Upload::kPoints ? "points" : "map";
}

}  // namespace

IngestService::IngestService(SharedAggregator& aggregator, Metrics* metrics, std::function<void(v1::Upload)> relay,
                             NowNs now_ns)
    : aggregator_(aggregator), metrics_(metrics), relay_(std::move(relay)), now_ns_(std::move(now_ns)) {}

IngestCounters IngestService::counters() const {
  return {accepted_.load(), late_.load(), malformed_.load(), rejected_streams_.load()};
}

void IngestService::countMalformed(const std::string& what) {
  ++malformed_;
  if (metrics_ != nullptr) metrics_->malformed(what);
}

grpc::Status IngestService::Push(grpc::ServerContext* /*context*/,
                                 grpc::ServerReaderWriter<v1::Ack, v1::Upload>* stream) {
  std::optional<std::uint32_t> child;
  std::string peer = "unknown";  // until the first well-formed upload names the child
  // The child stays live exactly as long as this stream, however the handler ends.
  struct Disconnect {
    SharedAggregator& aggregator;
    const std::optional<std::uint32_t>& child;
    ~Disconnect() {
      if (child) aggregator.with([this](MergeAggregator& core) { core.childDisconnected(*child); });
    }
  } disconnect{aggregator_, child};

  v1::Upload upload;
  while (stream->Read(&upload)) {
    const std::size_t bytes = upload.ByteSizeLong();
    std::uint32_t sender = 0;
    std::optional<MapMessage> map;
    std::optional<PointChunk> chunk;
    if (upload.payload_case() == v1::Upload::kMap) {
      auto converted = fromProto(upload.map());
      if (converted) {
        sender = converted->header.node;
        map = std::move(*converted);
      }
    } else if (upload.payload_case() == v1::Upload::kPoints) {
      auto converted = fromProto(upload.points());
      if (converted) {
        sender = converted->header.node;
        chunk = std::move(*converted);
      }
    }
    if (!map && !chunk) {
      if (metrics_ != nullptr) metrics_->bytesReceived(peer, kindOf(upload), bytes);
      countMalformed(upload.payload_case() == v1::Upload::PAYLOAD_NOT_SET ? "upload" : kindOf(upload));
      continue;
    }

    if (!child) {
      auto connected = aggregator_.with([&](MergeAggregator& core) { return core.childConnected(sender); });
      if (!connected) {
        ++rejected_streams_;
        countMalformed("sender");
        return toGrpcStatus(connected.error());
      }
      child = *connected;
      const auto name = peer_names_.find(*child);
      peer = name != peer_names_.end() ? name->second : std::to_string(*child);
    }
    if (metrics_ != nullptr) metrics_->bytesReceived(peer, kindOf(upload), bytes);

    const bool acknowledge = map ? handleMap(*map) : handlePoints(std::move(*chunk));
    if (!acknowledge) continue;
    v1::Ack ack;
    ack.set_sequence(upload.sequence());
    if (!stream->Write(ack)) break;  // the child went away; it re-sends what was not acknowledged
  }
  return grpc::Status::OK;
}

bool IngestService::handleMap(const MapMessage& map) {
  const auto arrival = aggregator_.with([&](MergeAggregator& core) { return core.onMap(map, now_ns_()); });
  if (!arrival) {
    countMalformed("map");
    return false;
  }
  if (*arrival == Arrival::kLate) {
    ++late_;
    if (metrics_ != nullptr) metrics_->lateMaps();
  } else {
    ++accepted_;
    if (metrics_ != nullptr) metrics_->mapsIn();
    if (on_arrival_) on_arrival_();
  }
  return true;
}

bool IngestService::handlePoints(PointChunk chunk) {
  const std::size_t points = chunk.points.size();
  auto outcome = aggregator_.with([&](MergeAggregator& core) { return core.onPoints(std::move(chunk), now_ns_()); });
  if (!outcome) {
    countMalformed("points");
    return false;
  }
  if (outcome->arrival == Arrival::kLate) {
    ++late_;
    if (metrics_ != nullptr) metrics_->lateMaps();
    return true;
  }
  ++accepted_;
  if (metrics_ != nullptr) metrics_->pointsIn(points);
  if (on_arrival_) on_arrival_();
  // Relayed outside the core's lock: the parent link only queues, but need not hold up others.
  if (outcome->arrival == Arrival::kRelay && outcome->relay && relay_) {
    v1::Upload upload;
    *upload.mutable_points() = toProto(*outcome->relay);
    relay_(std::move(upload));
    if (metrics_ != nullptr) metrics_->pointsOut(points);
  }
  return true;
}

}  // namespace fogmap
