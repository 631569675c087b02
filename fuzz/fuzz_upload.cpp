// libFuzzer target: what a merge-aggregator does with its children's uploads. Every upload takes
// the path of IngestService (the stream's child named by its first upload, the size bound,
// fromProto, the core's admission, MERGE or point storage) under a fake clock that only the input
// advances; the core is polled after every upload and drained at the end, and every epoch it emits
// must convert to the wire and back, as the parent or a subscriber receives it.
//
// Input: byte 0 chooses the aggregator: bits 0-1 the mode (madc, baseline, ext; 3 is madc again),
// bit 2 the intermediate "agg" instead of the root. Then records, each: a control byte (bits 0-1
// the stream, bits 2-6 how many 10 ms the clock advances before the upload, bit 7 the stream
// closes after it), a little-endian uint16 length, and that many bytes of a serialised
// fogmap.v1.Upload (fewer when the input ends first).
#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "common/geometry/geofence.hpp"
#include "common/config/topology.hpp"
#include "fuzz/fuzz_check.hpp"
#include "services/common/proto_convert.hpp"
#include "services/merge_aggregator/aggregator_core.hpp"

namespace fogmap {
namespace {

// 2023-11-14, epoch 17'000'000'000 of 100 ms: the seeds' maps are for epochs around it.
constexpr std::int64_t kStartNs = 1'700'000'000'000'000'000;
constexpr std::int64_t kTickNs = 10'000'000;
constexpr std::size_t kStreams = 4;

// sink (100) over edge-1 (1), edge-2 (2) and agg (101); agg over edge-3 (3) and edge-4 (4).
TopologyConfig fuzzTopology(Mode mode) {
  TopologyConfig t;
  t.name = "fuzz";
  t.mode = mode;
  t.madc.clustering.min_points = 3;
  // Small bounds, so that every refusal is within reach of a short input.
  t.admission.max_ellipsoids_per_map = 64;
  t.admission.max_map_bytes = 8192;
  const auto add = [&](std::uint32_t id, std::string name, Role role, std::string parent) {
    NodeConfig n;
    n.id = id;
    n.name = std::move(name);
    n.role = role;
    n.parent = std::move(parent);
    if (role == Role::kEdge) n.sensor = SensorConfig{};
    t.nodes.push_back(std::move(n));
  };
  add(100, "sink", Role::kAggregator, "");
  add(1, "edge-1", Role::kEdge, "sink");
  add(2, "edge-2", Role::kEdge, "sink");
  add(101, "agg", Role::kAggregator, "sink");
  add(3, "edge-3", Role::kEdge, "agg");
  add(4, "edge-4", Role::kEdge, "agg");
  return t;
}

// As IngestService: the sender an upload's header names, and a fingerprint of its content.
std::optional<std::uint32_t> senderOf(const v1::Upload& upload) {
  if (upload.has_map() && upload.map().has_header()) return upload.map().header().node();
  if (upload.has_points() && upload.points().has_header()) return upload.points().header().node();
  return std::nullopt;
}

std::uint64_t fingerprintOf(const v1::Upload& upload) {
  std::string bytes;
  if (upload.has_map()) upload.map().SerializeToString(&bytes);
  if (upload.has_points()) upload.points().SerializeToString(&bytes);
  return std::hash<std::string>{}(bytes);
}

void checkOutcome(const Outcome& outcome, const AggregatorConfig& config) {
  if (!outcome.ok()) {
    fuzz::check(!outcome.refused->message.empty(), "a refusal says why");
    return;
  }
  fuzz::check((outcome.arrival == Arrival::kRelay) == outcome.relay.has_value(), "a relay carries its chunk");
  fuzz::check(outcome.arrival != Arrival::kRelay || !config.is_root, "only an intermediate relays");
}

class Harness {
 public:
  explicit Harness(MergeAggregator core) : core_(std::move(core)) {}

  void upload(std::size_t stream_index, const v1::Upload& upload, std::int64_t now_ns) {
    std::optional<std::uint32_t>& child = streams_[stream_index];
    if (!child) {
      const auto sender = senderOf(upload);
      if (!sender) {
        core_.refuse(Refusal::kMalformed, "an upload without a header cannot name its sender");
        return;
      }
      const Expected<std::uint32_t> connected = core_.childConnected(*sender);
      if (!connected) return;  // the service ends the stream with the error
      child = *connected;
    }
    const std::size_t bytes = upload.ByteSizeLong();
    const UploadKey key{upload.sequence(), fingerprintOf(upload)};
    if (bytes > core_.config().admission.max_map_bytes) {
      core_.refuse(Refusal::kTooLarge, "upload of " + std::to_string(bytes) + " bytes, above admission max_map_bytes");
    } else if (upload.has_map()) {
      const Expected<MapMessage> map = fromProto(upload.map());
      if (!map) {
        fuzz::checkRejection(map.error(), "");
        core_.refuse(Refusal::kMalformed, map.error().message);
      } else {
        checkOutcome(core_.onMap(*child, key, *map, bytes, now_ns), core_.config());
      }
    } else if (upload.has_points()) {
      Expected<PointChunk> chunk = fromProto(upload.points());
      if (!chunk) {
        fuzz::checkRejection(chunk.error(), "");
        core_.refuse(Refusal::kMalformed, chunk.error().message);
      } else {
        checkOutcome(core_.onPoints(*child, key, std::move(*chunk), bytes, now_ns), core_.config());
      }
    } else {
      core_.refuse(Refusal::kMalformed, "an upload without a payload");
    }
  }

  void close(std::size_t stream_index, std::int64_t now_ns) {
    std::optional<std::uint32_t>& child = streams_[stream_index];
    if (child) core_.childDisconnected(*child, now_ns);
    child.reset();
  }

  void poll(std::int64_t now_ns) { emit(core_.poll(now_ns)); }
  void drain(std::int64_t now_ns) { emit(core_.drain(now_ns)); }

 private:
  // What the emitter does with each output: a map goes to the parent, a global map to the
  // subscribers (a baseline root clusters first); each must convert to the wire and back.
  void emit(std::vector<EpochOutput> outputs) {
    for (EpochOutput& out : outputs) {
      if (auto* job = std::get_if<BaselineJob>(&out.message)) {
        out.message = clusterCentrally(std::move(*job));
        core_.published(std::get<GlobalMapMessage>(out.message));
      }
      if (const auto* map = std::get_if<MapMessage>(&out.message)) {
        fuzz::checkOk(fromProto(toProto(*map)), "an emitted map converts to the wire and back");
      } else {
        const auto& global = std::get<GlobalMapMessage>(out.message);
        fuzz::checkOk(fromProto(toProto(global)), "a global map converts to the wire and back");
      }
      if (core_.config().is_root) fuzz::check(core_.queryGeofences("").ok(), "the root answers geofence queries");
    }
  }

  MergeAggregator core_;
  std::array<std::optional<std::uint32_t>, kStreams> streams_;
};

}  // namespace
}  // namespace fogmap

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace fogmap;
  if (size == 0) return 0;
  const Mode modes[] = {Mode::kMadc, Mode::kBaseline, Mode::kExt, Mode::kMadc};
  const TopologyConfig topology = fuzzTopology(modes[data[0] & 3U]);
  Expected<AggregatorConfig> config = aggregatorConfigFor(topology, (data[0] & 4U) != 0 ? "agg" : "sink");
  fuzz::check(config.ok(), "the fuzz topology configures its aggregators");
  Expected<MergeAggregator> core = MergeAggregator::create(std::move(*config));
  fuzz::check(core.ok(), "the fuzz topology's aggregators start");
  if (core->config().is_root) {
    fuzz::check(core->setGeofence(boxGeofence("front", {0.0, -4.0, -3.0}, {20.0, 4.0, 3.0})).ok(),
                "the root takes a geofence");
  }
  Harness harness(std::move(*core));

  std::int64_t now_ns = kStartNs;
  std::size_t pos = 1;
  while (pos + 3 <= size) {
    const std::uint8_t control = data[pos];
    const std::size_t length = data[pos + 1] | (std::size_t{data[pos + 2]} << 8);
    pos += 3;
    const std::size_t take = std::min(length, size - pos);
    v1::Upload upload;
    const bool parsed = upload.ParseFromArray(data + pos, static_cast<int>(take));
    pos += take;
    now_ns += ((control >> 2) & 31) * kTickNs;
    const std::size_t stream = control & 3U;
    if (parsed) harness.upload(stream, upload, now_ns);
    if ((control & 0x80U) != 0) harness.close(stream, now_ns);
    harness.poll(now_ns);
  }
  harness.drain(now_ns);
  return 0;
}
