// The aggregator's gRPC adapters over real sockets on loopback: children push over MapIngest.Push,
// subscribers receive global maps over GlobalMapService.Subscribe.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <limits>
#include <map>
#include <memory>
#include <random>
#include <string>

#include <grpcpp/grpcpp.h>

#include "common/perception/clustering.hpp"
#include "common/perception/madc.hpp"
#include "services/common/grpc_options.hpp"
#include "services/common/metrics.hpp"
#include "services/common/parent_link.hpp"
#include "services/common/proto_convert.hpp"
#include "services/merge_aggregator/aggregator_runtime.hpp"
#include "services/merge_aggregator/global_map_service.hpp"
#include "services/merge_aggregator/ingest_service.hpp"
#include "tests/support/eventually.hpp"
#include "tests/support/epoch_times.hpp"
#include "tests/support/test_server.hpp"
#include "tests/support/topology_builders.hpp"

namespace fogmap {
namespace {

using namespace std::chrono_literals;
// The server side of a call has no client-visible signal: tests poll it, bounded.
using test_support::eventually;

// Epoch k of the tests is E(k), at(k, offset_ms) a time in it (deadline at one level: offset 80).
using test_support::at;
using test_support::E;
using test_support::kE0;
using test_support::kMaxMessageBytes;
using test_support::kMs;
using test_support::kPeriodNs;
using test_support::kRoot;
using test_support::kT0;

constexpr auto kRpcTimeout = 10s;

// The aggregator's clock, set by the test: deadlines pass when the test says so.
class FakeClock {
 public:
  explicit FakeClock(std::int64_t start) : now_(start) {}
  void set(std::int64_t now_ns) { now_.store(now_ns); }
  NowNs fn() {
    return [this] { return now_.load(); };
  }

 private:
  std::atomic<std::int64_t> now_;
};

AggregatorConfig rootConfig(Mode mode, std::vector<std::uint32_t> edges) {
  AggregatorConfig config;
  config.node = kRoot;
  config.mode = mode;
  config.is_root = true;
  config.period_ms = 100.0;
  config.deadline_ms = 80.0;
  for (const auto edge : edges) config.children.push_back({edge, {edge}, "edge-" + std::to_string(edge)});
  return config;
}

MergeAggregator makeCore(AggregatorConfig config) {
  auto core = MergeAggregator::create(std::move(config));
  EXPECT_TRUE(core.ok());
  return std::move(core).value();
}

ParentLinkConfig linkTo(const std::string& target) {
  ParentLinkConfig config;
  config.target = target;
  config.max_message_bytes = kMaxMessageBytes;
  return config;
}

// An aggregator served in-process on 127.0.0.1, port chosen by the OS, on the given clock; with a
// parent target it is an intermediate that uploads (and relays) through a real ParentLink.
class AggregatorServer {
 public:
  AggregatorServer(AggregatorConfig config, FakeClock& clock, const std::string& parent_target = "",
                   Metrics* metrics = nullptr)
      : aggregator_(makeCore(std::move(config))),
        parent_(parent_target.empty()
                    ? nullptr
                    : std::make_unique<ParentLink>(linkTo(parent_target), ParentLinkHooks{})),
        ingest_(aggregator_, metrics, parent_ ? relay() : Relay{}, clock.fn()),
        global_maps_(aggregator_, metrics, 16, 20ms),
        emitter_(aggregator_,
                 EmitterSinks{parent_ ? toParent() : std::function<void(v1::Upload)>{},
                              [this](const GlobalMapMessage& m) { global_maps_.publish(m); }, {}},
                 metrics, clock.fn()) {
    ingest_.onArrival([this] { emitter_.wake(); });
    grpc::ServerBuilder builder;
    configureServer(builder, kMaxMessageBytes);
    builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port_);
    builder.RegisterService(&ingest_);
    builder.RegisterService(&global_maps_);
    server_ = builder.BuildAndStart();
    channel_ = makeChannel(target(), kMaxMessageBytes);
  }
  ~AggregatorServer() {
    ingest_.stopAccepting();
    emitter_.stop();
    global_maps_.shutdown(0ms);
    if (server_) server_->Shutdown(std::chrono::system_clock::now() + 2s);
  }

  bool started() const { return server_ != nullptr && port_ != 0; }
  std::string target() const { return "127.0.0.1:" + std::to_string(port_); }
  std::unique_ptr<v1::MapIngest::Stub> ingestStub() { return v1::MapIngest::NewStub(channel_); }
  std::unique_ptr<v1::GlobalMapService::Stub> globalStub() { return v1::GlobalMapService::NewStub(channel_); }

  SharedAggregator& aggregator() { return aggregator_; }
  IngestService& ingest() { return ingest_; }
  GlobalMapService& globalMaps() { return global_maps_; }
  Emitter& emitter() { return emitter_; }
  template <class F>
  decltype(auto) core(F&& f) {
    return aggregator_.with(std::forward<F>(f));
  }

 private:
  std::function<void(v1::Upload)> toParent() {
    return [this](v1::Upload upload) { parent_->send(std::move(upload)); };
  }
  Relay relay() {
    return [this](v1::Upload upload, RelaySettled settled) { parent_->send(std::move(upload), std::move(settled)); };
  }

  SharedAggregator aggregator_;
  std::unique_ptr<ParentLink> parent_;
  IngestService ingest_;
  GlobalMapService global_maps_;
  Emitter emitter_;
  int port_ = 0;
  std::unique_ptr<grpc::Server> server_;
  std::shared_ptr<grpc::Channel> channel_;
};

// One child's upload stream.
class Child {
 public:
  explicit Child(v1::MapIngest::Stub& stub) {
    context_.set_deadline(std::chrono::system_clock::now() + kRpcTimeout);
    context_.set_wait_for_ready(true);  // a loaded machine may be slow to connect: wait, do not fail
    stream_ = stub.Push(&context_);
  }
  bool write(std::uint64_t sequence, v1::Upload upload) {
    upload.set_sequence(sequence);
    return stream_->Write(upload);
  }
  bool writeMap(std::uint64_t sequence, const MapMessage& map) {
    v1::Upload upload;
    *upload.mutable_map() = toProto(map);
    return write(sequence, std::move(upload));
  }
  bool writePoints(std::uint64_t sequence, const PointChunk& chunk) {
    v1::Upload upload;
    *upload.mutable_points() = toProto(chunk);
    return write(sequence, std::move(upload));
  }
  // The next answer, or nullopt when the stream ended.
  std::optional<v1::Ack> readAck() {
    v1::Ack ack;
    if (!stream_->Read(&ack)) return std::nullopt;
    return ack;
  }
  // Reads the next answer and checks its sequence and status.
  ::testing::AssertionResult answered(std::uint64_t sequence, v1::AckStatus status = v1::ACK_STATUS_APPLIED) {
    const auto ack = readAck();
    if (!ack) return ::testing::AssertionFailure() << "the stream ended before upload " << sequence << " was answered";
    if (ack->sequence() != sequence || ack->status() != status) {
      return ::testing::AssertionFailure() << "expected upload " << sequence << " answered " << v1::AckStatus_Name(status)
                                           << ", got " << ack->sequence() << " " << v1::AckStatus_Name(ack->status())
                                           << " (" << ack->reason() << ")";
    }
    return ::testing::AssertionSuccess();
  }
  grpc::Status finish() {
    stream_->WritesDone();
    return stream_->Finish();
  }

 private:
  grpc::ClientContext context_;
  std::unique_ptr<grpc::ClientReaderWriter<v1::Upload, v1::Ack>> stream_;
};

// One Subscribe call.
class Subscription {
 public:
  Subscription(v1::GlobalMapService::Stub& stub, bool point_labels, bool on_time_only = false) {
    context_.set_deadline(std::chrono::system_clock::now() + kRpcTimeout);
    context_.set_wait_for_ready(true);
    v1::SubscribeRequest request;
    request.set_include_point_labels(point_labels);
    request.set_on_time_only(on_time_only);
    reader_ = stub.Subscribe(&context_, request);
  }
  ~Subscription() { context_.TryCancel(); }
  std::optional<v1::GlobalMap> next() {
    v1::GlobalMap map;
    if (!reader_->Read(&map)) return std::nullopt;
    return map;
  }
  // The call's status, once the stream has ended (next() returned nullopt).
  grpc::Status finish() { return reader_->Finish(); }

 private:
  grpc::ClientContext context_;
  std::unique_ptr<grpc::ClientReader<v1::GlobalMap>> reader_;
};

Ellipsoid randomEllipsoid(std::mt19937_64& rng, std::uint32_t node, std::uint64_t frame, std::uint32_t index) {
  std::uniform_real_distribution<double> pos(-5.0, 5.0);
  std::uniform_real_distribution<double> radius(0.4, 1.5);
  Ellipsoid e;
  e.id = {node, frame, index};
  e.center = {pos(rng), pos(rng), 1.0};
  const Eigen::Vector3d r(radius(rng), radius(rng), radius(rng));
  e.shape = r.cwiseAbs2().asDiagonal();
  e.point_count = 15;
  return e;
}

MapMessage randomMap(std::mt19937_64& rng, std::uint32_t node, std::uint64_t epoch, int count) {
  std::vector<Ellipsoid> ellipsoids;
  for (int k = 0; k < count; ++k) ellipsoids.push_back(randomEllipsoid(rng, node, epoch, static_cast<std::uint32_t>(k)));
  MapMessage message;
  message.header.node = node;
  message.header.epoch = epoch;
  message.header.sensor_time_ns = kT0;
  message.header.contributing_nodes = {node};
  message.map = localMap(std::move(ellipsoids));
  return message;
}

// The map as the receiver sees it: the wire may be less precise than the domain types (float32
// ellipsoids), and the aggregator can only merge what it received.
Map overTheWire(const MapMessage& message) {
  auto received = fromProto(toProto(message));
  EXPECT_TRUE(received.ok());
  return received.ok() ? received->map : Map{};
}

// A global map as a subscriber decodes it (its ellipsoids on the compact wire).
Map overTheWire(const Map& global) {
  auto received = throughGlobalWire(global);
  EXPECT_TRUE(received.ok());
  return received.ok() ? *received : Map{};
}

// The number of objects a subscriber decodes from a global map.
std::size_t objectCount(const v1::GlobalMap& wire) {
  auto decoded = fromProto(wire);
  EXPECT_TRUE(decoded.ok()) << decoded.error().message;
  return decoded.ok() ? decoded->map.objects.size() : 0;
}

// Sum of the counter series of `family` that carry the label (any series when the label is empty).
double counterValue(Metrics& metrics, const std::string& family, const std::pair<std::string, std::string>& label) {
  double sum = 0.0;
  for (const auto& f : metrics.registry().Collect()) {
    if (f.name != family) continue;
    for (const auto& m : f.metric) {
      const bool match = label.first.empty() || std::any_of(m.label.begin(), m.label.end(), [&](const auto& l) {
                           return l.name == label.first && l.value == label.second;
                         });
      if (match) sum += m.counter.value;
    }
  }
  return sum;
}

// A sensor's scan: three blobs of 25 points in a row along x from x0.
Cloud blobRow(std::mt19937_64& rng, float x0) {
  std::normal_distribution<float> jitter(0.0F, 0.1F);
  Cloud cloud;
  for (int blob = 0; blob < 3; ++blob) {
    for (int i = 0; i < 25; ++i) {
      cloud.push_back({x0 + 4.0F * static_cast<float>(blob) + jitter(rng), jitter(rng), 1.0F + jitter(rng), 0.0F});
    }
  }
  return cloud;
}

PointChunk wholeScan(std::uint32_t node, std::uint64_t epoch, const Cloud& cloud, const std::vector<std::int32_t>& labels) {
  PointChunk chunk;
  chunk.header.node = node;
  chunk.header.epoch = epoch;
  chunk.header.sensor_time_ns = kT0;
  chunk.header.contributing_nodes = {node};
  chunk.total_points = static_cast<std::uint32_t>(cloud.size());
  chunk.points = cloud;
  chunk.labels = labels;
  return chunk;
}

// A sensor's scan (blobRow) as two point chunks.
std::vector<PointChunk> scanChunks(std::mt19937_64& rng, std::uint32_t node, std::uint64_t epoch, float x0) {
  const Cloud cloud = blobRow(rng, x0);
  std::vector<PointChunk> chunks(2);
  for (std::uint32_t k = 0; k < 2; ++k) {
    auto& chunk = chunks[k];
    chunk.header.node = node;
  chunk.header.epoch = epoch;
  chunk.header.sensor_time_ns = kT0;
  chunk.header.contributing_nodes = {node};
    chunk.chunk = k;
    chunk.chunk_count = 2;
    chunk.first_point = k == 0 ? 0 : 40;
    chunk.total_points = static_cast<std::uint32_t>(cloud.size());
    chunk.points.assign(cloud.begin() + (k == 0 ? 0 : 40), k == 0 ? cloud.begin() + 40 : cloud.end());
  }
  return chunks;
}

TEST(AggregatorService, PushFromTwoChildrenPublishesTheMergedGlobalMap) {
  FakeClock clock(at(1, 5));
  AggregatorServer server(rootConfig(Mode::kMadc, {1, 2}), clock);
  ASSERT_TRUE(server.started());
  server.emitter().start();
  auto global_stub = server.globalStub();
  Subscription subscription(*global_stub, false);
  ASSERT_TRUE(eventually([&] { return server.globalMaps().subscriberCount() == 1; }));

  std::mt19937_64 rng(31);
  auto ingest_stub = server.ingestStub();
  Child a(*ingest_stub);
  Child b(*ingest_stub);
  // Epoch 1 makes both children live (whether it is emitted merged or child 2's map arrives late,
  // it is answered); epoch 2 must then wait for both.
  ASSERT_TRUE(a.writeMap(1, randomMap(rng, 1, E(1), 3)));
  ASSERT_TRUE(a.answered(1));
  ASSERT_TRUE(b.writeMap(1, randomMap(rng, 2, E(1), 3)));
  const auto first = b.readAck();
  ASSERT_TRUE(first.has_value());
  EXPECT_NE(first->status(), v1::ACK_STATUS_REFUSED) << first->reason();
  clock.set(at(2, 5));
  const std::vector<MapMessage> epoch2{randomMap(rng, 1, E(2), 10), randomMap(rng, 2, E(2), 10)};
  ASSERT_TRUE(a.writeMap(2, epoch2[0]));
  ASSERT_TRUE(a.answered(2));
  ASSERT_TRUE(b.writeMap(2, epoch2[1]));
  ASSERT_TRUE(b.answered(2));

  std::optional<GlobalMapMessage> received;
  for (int i = 0; i < 3 && !received; ++i) {  // epoch 1 (once, maybe a revision), then epoch 2
    const auto map = subscription.next();
    ASSERT_TRUE(map.has_value()) << "the subscription ended before epoch 2";
    auto converted = fromProto(*map);
    ASSERT_TRUE(converted.ok()) << converted.error().message;
    if (converted->header.epoch == E(2)) received = std::move(*converted);
  }
  ASSERT_TRUE(received.has_value());
  const std::vector<Map> maps{overTheWire(epoch2[0]), overTheWire(epoch2[1])};
  EXPECT_EQ(received->map, overTheWire(mergeAll(maps).map)) << "the merge of the decoded maps, as published";
  EXPECT_EQ(received->header.node, kRoot);
  EXPECT_EQ(received->header.contributing_nodes, (std::vector<std::uint32_t>{1, 2}));
  EXPECT_TRUE(received->header.missing_nodes.empty());
  EXPECT_FALSE(received->late);
  EXPECT_EQ(received->published_time_ns, at(2, 5));

  EXPECT_TRUE(a.finish().ok());
  EXPECT_TRUE(b.finish().ok());
  EXPECT_TRUE(eventually([&] { return server.core([](MergeAggregator& core) { return core.liveChildren(at(4, 0)); }) == 0U; }))
      << "a closed stream is a dead child once its grace has passed";
}

// The gauge of `family` with the label, or nullopt when there is no such series.
std::optional<double> gaugeValue(Metrics& metrics, const std::string& family,
                                 const std::pair<std::string, std::string>& label) {
  for (const auto& f : metrics.registry().Collect()) {
    if (f.name != family) continue;
    for (const auto& m : f.metric) {
      const bool match = label.first.empty() || std::any_of(m.label.begin(), m.label.end(), [&](const auto& l) {
                           return l.name == label.first && l.value == label.second;
                         });
      if (match) return m.gauge.value;
    }
  }
  return std::nullopt;
}

TEST(AggregatorService, RootExportsObjectsAndMissingSensorsOfEachLiveGlobalMap) {
  FakeClock clock(at(2, 5));
  Metrics metrics("", "merge-aggregator", "sink");  // registry only, nothing served
  SharedAggregator aggregator(makeCore(rootConfig(Mode::kMadc, {1, 2})));
  std::vector<GlobalMapMessage> published;
  Emitter emitter(aggregator, EmitterSinks{{}, [&](const GlobalMapMessage& m) { published.push_back(m); }, {}},
                  &metrics, clock.fn());
  emitter.sensorNames({{1, "edge-1"}, {2, "edge-2"}});

  std::mt19937_64 rng(5);
  const MapMessage map = randomMap(rng, 1, E(2), 6);
  aggregator.with([&](MergeAggregator& core) {
    ASSERT_TRUE(core.childConnected(1).ok());
    ASSERT_TRUE(core.onMap(1, {1, 1}, map, 100, clock.fn()()).ok());
  });
  clock.set(at(3, 0));  // past epoch 2's deadline: emitted without edge-2
  EXPECT_GE(emitter.pollOnce(), 1U);
  const auto live = std::find_if(published.begin(), published.end(),
                                 [](const GlobalMapMessage& m) { return m.header.epoch == E(2); });
  ASSERT_NE(live, published.end());
  EXPECT_EQ(gaugeValue(metrics, "fogmap_global_objects", {}), static_cast<double>(live->map.objects.size()));
  EXPECT_EQ(live->map.objects.size(), map.map.objects.size()) << "one sensor's clusters are not merged further";
  EXPECT_EQ(gaugeValue(metrics, "fogmap_sensor_missing", {"sensor", "edge-1"}), 0.0);
  EXPECT_EQ(gaugeValue(metrics, "fogmap_sensor_missing", {"sensor", "edge-2"}), 1.0);
}

TEST(AggregatorService, EveryUploadIsAnsweredWithItsStatusAndRefusalsAreCounted) {
  Metrics metrics("", "merge-aggregator", "sink");  // registry only, nothing served
  FakeClock clock(at(1, 5));
  AggregatorServer server(rootConfig(Mode::kMadc, {1, 2}), clock, "", &metrics);
  ASSERT_TRUE(server.started());
  std::mt19937_64 rng(32);
  auto stub = server.ingestStub();
  Child child(*stub);

  ASSERT_TRUE(child.writeMap(1, randomMap(rng, 1, E(1), 2)));
  v1::Upload bad;
  *bad.mutable_map() = toProto(randomMap(rng, 1, E(2), 2), EllipsoidWire::kExact);
  bad.mutable_map()->mutable_objects(0)->mutable_ellipsoids(0)->mutable_shape()->RemoveLast();  // 5 values
  ASSERT_TRUE(child.write(2, bad));
  ASSERT_TRUE(child.write(3, v1::Upload{}));  // no payload at all
  ASSERT_TRUE(child.writeMap(4, randomMap(rng, 2, E(2), 2)));  // speaks for node 2
  ASSERT_TRUE(child.writeMap(5, randomMap(rng, 1, E(40), 2)));  // 4 s ahead
  ASSERT_TRUE(child.writeMap(6, randomMap(rng, 1, E(2), 2)));

  EXPECT_TRUE(child.answered(1));
  for (std::uint64_t sequence : {2, 3, 4, 5}) {
    const auto ack = child.readAck();
    ASSERT_TRUE(ack.has_value());
    EXPECT_EQ(ack->sequence(), sequence);
    EXPECT_EQ(ack->status(), v1::ACK_STATUS_REFUSED);
    EXPECT_EQ(ack->code(), static_cast<int>(grpc::StatusCode::INVALID_ARGUMENT));
    EXPECT_FALSE(ack->reason().empty()) << "a refusal says why";
  }
  EXPECT_TRUE(child.answered(6));
  // Epoch 1 is emitted at its deadline; child 2 never connected, so it is not waited for.
  clock.set(at(1, 80));
  EXPECT_EQ(server.emitter().pollOnce(), 1U);
  // Child 2's map for the emitted epoch is merged into a revision and answered LATE.
  Child late(*stub);
  ASSERT_TRUE(late.writeMap(1, randomMap(rng, 2, E(1), 4)));
  EXPECT_TRUE(late.answered(1, v1::ACK_STATUS_LATE));
  EXPECT_EQ(server.emitter().pollOnce(), 1U) << "the revision";

  const auto counters = server.core([](MergeAggregator& core) { return core.counters(); });
  EXPECT_EQ(counters.refused.at(Refusal::kMalformed), 2U);
  EXPECT_EQ(counters.refused.at(Refusal::kForgedNode), 1U);
  EXPECT_EQ(counters.refused.at(Refusal::kClockSkew), 1U);
  EXPECT_EQ(counters.accepted, 2U);
  EXPECT_EQ(counters.late, 1U);
  EXPECT_EQ(counterValue(metrics, "fogmap_refused_uploads_total", {"reason", "malformed"}), 2.0);
  EXPECT_EQ(counterValue(metrics, "fogmap_refused_uploads_total", {"reason", "forged_node"}), 1.0);
  EXPECT_EQ(counterValue(metrics, "fogmap_refused_uploads_total", {"reason", "clock_skew"}), 1.0);
  EXPECT_EQ(counterValue(metrics, "fogmap_maps_in_total", {}), 2.0);
  EXPECT_EQ(counterValue(metrics, "fogmap_late_maps_total", {}), 1.0);
  EXPECT_EQ(counterValue(metrics, "fogmap_late_emits_total", {}), 1.0);
  EXPECT_GT(counterValue(metrics, "fogmap_bytes_received_total", {"peer", "1"}), 0.0) << "named by the child's id";
  EXPECT_TRUE(child.finish().ok());
  EXPECT_TRUE(late.finish().ok());
}

TEST(AggregatorService, MessagesAboveTheSizeBoundsAreRefusedAndOtherStreamsGoOn) {
  Metrics metrics("", "merge-aggregator", "sink");
  FakeClock clock(at(1, 5));
  AggregatorServer server(rootConfig(Mode::kMadc, {1, 2}), clock, "", &metrics);
  ASSERT_TRUE(server.started());
  std::mt19937_64 rng(39);
  auto plain_stub = server.ingestStub();
  Child other(*plain_stub);
  ASSERT_TRUE(other.writeMap(1, randomMap(rng, 2, E(1), 2)));
  ASSERT_TRUE(other.answered(1));
  auto channel = makeChannel(server.target(), 256U << 20);  // the client would send it
  auto stub = v1::MapIngest::NewStub(channel);
  Child child(*stub);
  ASSERT_TRUE(child.writeMap(1, randomMap(rng, 1, E(1), 2)));
  ASSERT_TRUE(child.answered(1));
  // Above admission max_map_bytes (8 MiB), below the transport limit: answered and counted.
  v1::Upload big;
  *big.mutable_map() = toProto(randomMap(rng, 1, E(1), 1), EllipsoidWire::kExact);
  big.mutable_map()->mutable_objects(0)->mutable_ellipsoids(0)->mutable_shape()->Resize((9U << 20) / 4, 1.0F);
  ASSERT_TRUE(child.write(2, big));
  const auto too_large = child.readAck();
  ASSERT_TRUE(too_large.has_value());
  EXPECT_EQ(too_large->sequence(), 2U);
  EXPECT_EQ(too_large->status(), v1::ACK_STATUS_REFUSED);
  EXPECT_EQ(too_large->code(), static_cast<int>(grpc::StatusCode::RESOURCE_EXHAUSTED)) << too_large->reason();
  server.emitter().pollOnce();
  EXPECT_EQ(counterValue(metrics, "fogmap_refused_uploads_total", {"reason", "too_large"}), 1.0);
  // Above the transport limit: gRPC ends the stream RESOURCE_EXHAUSTED before the service sees it.
  v1::Upload huge;
  *huge.mutable_map() = toProto(randomMap(rng, 1, E(1), 1), EllipsoidWire::kExact);
  huge.mutable_map()->mutable_objects(0)->mutable_ellipsoids(0)->mutable_shape()->Resize((kMaxMessageBytes / 4) + 16, 1.0F);
  (void)child.write(3, huge);
  EXPECT_FALSE(child.readAck().has_value());
  const auto status = child.finish();
  EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << status.error_message();
  // The other child's stream goes on.
  ASSERT_TRUE(other.writeMap(2, randomMap(rng, 2, E(2), 2)));
  EXPECT_TRUE(other.answered(2));
  EXPECT_TRUE(other.finish().ok());
}

// Each class of hostile upload, on a stream of its own next to a legitimate one: answered REFUSED
// with its gRPC code and a reason naming the rule, counted by reason in
// fogmap_refused_uploads_total, while every legitimate upload is applied and published.
TEST(AggregatorService, HostileUploadsAreRefusedWithTheirCodeWhileALegitimateStreamIsApplied) {
  Metrics metrics("", "merge-aggregator", "sink");
  FakeClock clock(at(1, 5));
  AggregatorServer server(rootConfig(Mode::kMadc, {1, 2}), clock, "", &metrics);
  ASSERT_TRUE(server.started());
  auto global_stub = server.globalStub();
  Subscription subscription(*global_stub, false);
  ASSERT_TRUE(eventually([&] { return server.globalMaps().subscriberCount() == 1; }));
  std::mt19937_64 rng(41);
  auto stub = server.ingestStub();
  Child legitimate(*stub);
  std::uint64_t legitimate_sequence = 0;
  std::int64_t epoch = 1;
  // One legitimate map of the current epoch, answered APPLIED; then the epoch is published.
  const auto legitimate_upload = [&] {
    ASSERT_TRUE(legitimate.writeMap(++legitimate_sequence, randomMap(rng, 2, E(epoch), 3)));
    const auto ack = legitimate.readAck();
    ASSERT_TRUE(ack.has_value());
    EXPECT_EQ(ack->sequence(), legitimate_sequence);
    EXPECT_EQ(ack->status(), v1::ACK_STATUS_APPLIED) << ack->reason();
    EXPECT_EQ(ack->code(), 0);
  };
  legitimate_upload();

  const auto proto = [&](std::uint32_t node, std::uint64_t e) {
    v1::Upload upload;
    *upload.mutable_map() = toProto(randomMap(rng, node, e, 2), EllipsoidWire::kExact);
    return upload;
  };
  struct Attack {
    std::string what;
    v1::Upload upload;
    const char* reason;        // the counter's label
    grpc::StatusCode code;
    std::string says;          // in the answer's reason
    bool own_epoch = false;    // sent with its own epoch, not the current one
  };
  std::vector<Attack> attacks;
  {
    v1::Upload upload = proto(1, E(1));
    auto* shape = upload.mutable_map()->mutable_objects(0)->mutable_ellipsoids(0)->mutable_shape();
    for (int i = 0; i < shape->size(); ++i) shape->Set(i, 0.0F);
    shape->Set(0, -1.0F);  // xx < 0: not positive definite
    shape->Set(3, 1.0F);
    shape->Set(5, 1.0F);
    attacks.push_back({"non-positive-definite shape", upload, "malformed", grpc::StatusCode::INVALID_ARGUMENT,
                       "shape is not positive definite"});
  }
  {
    v1::Upload upload = proto(1, E(1));
    upload.mutable_map()->mutable_objects(0)->mutable_ellipsoids(0)->mutable_center()->Set(
        1, std::numeric_limits<float>::quiet_NaN());
    attacks.push_back({"NaN centre", upload, "malformed", grpc::StatusCode::INVALID_ARGUMENT, "center is not finite"});
  }
  {
    v1::Upload upload = proto(1, E(1));
    upload.mutable_map()->mutable_objects(0)->mutable_ellipsoids(0)->mutable_center()->Set(0, 1e30F);
    attacks.push_back({"centre at 1e30", upload, "out_of_world", grpc::StatusCode::INVALID_ARGUMENT, "world extent"});
  }
  attacks.push_back({"epoch 2^63", proto(1, 1ULL << 63), "clock_skew", grpc::StatusCode::INVALID_ARGUMENT,
                     "admission window", true});
  attacks.push_back({"epoch 0", proto(1, 0), "clock_skew", grpc::StatusCode::INVALID_ARGUMENT, "admission window",
                     true});
  attacks.push_back({"map of another node", proto(2, E(1)), "forged_node", grpc::StatusCode::INVALID_ARGUMENT,
                     "speaks for one node only"});
  attacks.push_back({"no payload", v1::Upload{}, "malformed", grpc::StatusCode::INVALID_ARGUMENT, "without a payload"});
  {
    v1::Upload upload = proto(1, E(1));
    upload.mutable_map()->mutable_objects(0)->mutable_ellipsoids(0)->mutable_shape()->Resize((9U << 20) / 4, 1.0F);
    attacks.push_back({"9 MiB map", upload, "too_large", grpc::StatusCode::RESOURCE_EXHAUSTED, "max_map_bytes"});
  }

  // Each attack on a stream of its own that speaks for child 1 (a legitimate first upload names
  // it); child 1's sequences go on across its streams, as a restarted sender's do.
  std::map<std::string, double> expected_counts;
  std::uint64_t attacker_sequence = 0;
  for (auto& attack : attacks) {
    SCOPED_TRACE(attack.what);
    auto channel = makeChannel(server.target(), 256U << 20);
    auto attacker_stub = v1::MapIngest::NewStub(channel);
    Child attacker(*attacker_stub);
    ASSERT_TRUE(attacker.writeMap(++attacker_sequence, randomMap(rng, 1, E(epoch), 1)));
    ASSERT_TRUE(attacker.answered(attacker_sequence));
    // The current epoch, so that only the attack's own flaw refuses it (ellipsoid ids follow the
    // header's epoch: their frames are left out on the wire).
    if (!attack.own_epoch && attack.upload.has_map()) {
      attack.upload.mutable_map()->mutable_header()->set_epoch(E(epoch));
    }
    ASSERT_TRUE(attacker.write(++attacker_sequence, attack.upload));
    const auto ack = attacker.readAck();
    ASSERT_TRUE(ack.has_value()) << "the stream ended unanswered";
    EXPECT_EQ(ack->sequence(), attacker_sequence);
    EXPECT_EQ(ack->status(), v1::ACK_STATUS_REFUSED);
    EXPECT_EQ(ack->code(), static_cast<int>(attack.code)) << ack->reason();
    EXPECT_NE(ack->reason().find(attack.says), std::string::npos) << ack->reason();
    ++expected_counts[attack.reason];
    EXPECT_TRUE(attacker.finish().ok()) << "a refusal does not end the stream";
    // Next to it, the legitimate stream is applied, epoch after epoch.
    clock.set(at(++epoch, 5));
    legitimate_upload();
  }
  // A stream from a node that is no child: answered REFUSED, then ended, both INVALID_ARGUMENT.
  {
    Child stranger(*stub);
    ASSERT_TRUE(stranger.writeMap(1, randomMap(rng, 7, E(epoch), 2)));
    const auto ack = stranger.readAck();
    ASSERT_TRUE(ack.has_value());
    EXPECT_EQ(ack->status(), v1::ACK_STATUS_REFUSED);
    EXPECT_EQ(ack->code(), static_cast<int>(grpc::StatusCode::INVALID_ARGUMENT));
    EXPECT_NE(ack->reason().find("neither a child"), std::string::npos) << ack->reason();
    EXPECT_EQ(stranger.finish().error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    ++expected_counts["unknown_node"];
  }

  // Every epoch published, each with the legitimate child's map and nothing of the attacks.
  clock.set(at(epoch, 80));
  server.emitter().pollOnce();
  for (std::int64_t k = 1; k <= epoch; ++k) {
    const auto map = subscription.next();
    ASSERT_TRUE(map.has_value()) << "epoch " << k << " was not published";
    EXPECT_EQ(map->header().epoch(), E(k));
    EXPECT_EQ(map->revision(), 0U);
    const auto global = fromProto(*map);
    ASSERT_TRUE(global.ok()) << global.error().message;
    EXPECT_NE(std::find(global->header.contributing_nodes.begin(), global->header.contributing_nodes.end(), 2U),
              global->header.contributing_nodes.end())
        << "epoch " << k;
  }
  for (const auto& [reason, count] : expected_counts) {
    EXPECT_EQ(counterValue(metrics, "fogmap_refused_uploads_total", {"reason", reason}), count) << reason;
  }
  EXPECT_EQ(counterValue(metrics, "fogmap_refused_uploads_total", {}), static_cast<double>(attacks.size() + 1));
  EXPECT_EQ(server.core([](MergeAggregator& core) { return core.counters().accepted; }),
            legitimate_sequence + attacks.size());
  EXPECT_TRUE(legitimate.finish().ok());
}

TEST(AggregatorService, StreamFromANodeThatIsNoChildIsRefused) {
  FakeClock clock(at(1, 5));
  AggregatorServer server(rootConfig(Mode::kMadc, {1, 2}), clock);
  ASSERT_TRUE(server.started());
  std::mt19937_64 rng(33);
  auto stub = server.ingestStub();
  Child stranger(*stub);
  ASSERT_TRUE(stranger.writeMap(1, randomMap(rng, 7, E(1), 2)));
  // The upload is answered like any other (so the sender settles it), then the stream ends.
  const auto ack = stranger.readAck();
  ASSERT_TRUE(ack.has_value());
  EXPECT_EQ(ack->sequence(), 1U);
  EXPECT_EQ(ack->status(), v1::ACK_STATUS_REFUSED);
  EXPECT_EQ(ack->code(), static_cast<int>(grpc::StatusCode::INVALID_ARGUMENT));
  EXPECT_NE(ack->reason().find("node 7 is neither a child"), std::string::npos) << ack->reason();
  EXPECT_FALSE(stranger.readAck().has_value());
  const auto status = stranger.finish();
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << status.error_message();
  EXPECT_EQ(server.core([](MergeAggregator& core) { return core.counters().refused.at(Refusal::kUnknownNode); }), 1U);
  EXPECT_EQ(server.core([](MergeAggregator& core) { return core.liveChildren(at(1, 5)); }), 0U);
}

TEST(AggregatorService, OnTimeOnlySubscribersSkipLateRevisions) {
  FakeClock clock(at(1, 5));
  AggregatorServer server(rootConfig(Mode::kMadc, {1, 2}), clock);
  ASSERT_TRUE(server.started());
  auto global_stub = server.globalStub();
  Subscription everything(*global_stub, false);
  Subscription on_time(*global_stub, false, /*on_time_only=*/true);
  ASSERT_TRUE(eventually([&] { return server.globalMaps().subscriberCount() == 2; }));

  std::mt19937_64 rng(36);
  auto stub = server.ingestStub();
  Child a(*stub);
  Child b(*stub);
  ASSERT_TRUE(a.writeMap(1, randomMap(rng, 1, E(1), 3)));
  ASSERT_TRUE(a.answered(1));
  clock.set(at(1, 80));
  ASSERT_EQ(server.emitter().pollOnce(), 1U);
  ASSERT_TRUE(b.writeMap(1, randomMap(rng, 2, E(1), 3)));  // after the deadline: a revision
  ASSERT_TRUE(b.answered(1, v1::ACK_STATUS_LATE));
  ASSERT_EQ(server.emitter().pollOnce(), 1U);
  clock.set(at(2, 5));
  ASSERT_TRUE(a.writeMap(2, randomMap(rng, 1, E(2), 3)));
  ASSERT_TRUE(a.answered(2));
  ASSERT_TRUE(b.writeMap(2, randomMap(rng, 2, E(2), 3)));
  ASSERT_TRUE(b.answered(2));
  ASSERT_EQ(server.emitter().pollOnce(), 1U);

  std::vector<std::pair<std::uint64_t, std::uint32_t>> all;  // (epoch, revision)
  for (int i = 0; i < 3; ++i) {
    const auto map = everything.next();
    ASSERT_TRUE(map.has_value());
    all.emplace_back(map->header().epoch(), map->revision());
    EXPECT_EQ(map->late(), map->revision() > 0);
  }
  EXPECT_EQ(all, (std::vector<std::pair<std::uint64_t, std::uint32_t>>{{E(1), 0}, {E(1), 1}, {E(2), 0}}));
  for (const std::uint64_t epoch : {E(1), E(2)}) {
    const auto map = on_time.next();
    ASSERT_TRUE(map.has_value());
    EXPECT_EQ(map->header().epoch(), epoch);
    EXPECT_FALSE(map->late());
  }
  EXPECT_TRUE(a.finish().ok());
  EXPECT_TRUE(b.finish().ok());
}

TEST(AggregatorService, SlowSubscriberLosesItsOldestMapsCountedAndExported) {
  Metrics metrics("", "merge-aggregator", "sink");
  FakeClock clock(at(1, 5));
  AggregatorServer server(rootConfig(Mode::kMadc, {1}), clock, "", &metrics);  // queues of 16
  ASSERT_TRUE(server.started());
  auto global_stub = server.globalStub();
  Subscription stalled(*global_stub, /*point_labels=*/true);  // never reads until the end
  ASSERT_TRUE(eventually([&] { return server.globalMaps().subscriberCount() == 1; }));
  // 1 MB maps: the transport's flow-control window holds a few, the queue 16, the rest are dropped.
  std::mt19937_64 rng(40);
  GlobalMapMessage big;
  big.header.node = kRoot;
  big.map = randomMap(rng, 1, E(1), 1).map;
  GlobalMapMessage labelled = big;
  labelled.point_labels.push_back({1, std::vector<std::int32_t>(250'000, 3)});
  constexpr int kPublished = 80;
  for (int i = 0; i < kPublished; ++i) {
    labelled.header.epoch = E(i);
    server.globalMaps().publish(labelled);
  }
  const std::uint64_t dropped = server.globalMaps().droppedMessages();
  EXPECT_GT(dropped, 0U);
  EXPECT_LE(dropped, static_cast<std::uint64_t>(kPublished - 16));
  EXPECT_EQ(counterValue(metrics, "fogmap_subscriber_drops_total", {}), static_cast<double>(dropped));
  // What was not dropped still arrives, oldest first, and the newest map is among it.
  std::uint64_t received = 0;
  std::uint64_t last_epoch = 0;
  while (received + dropped < kPublished) {
    const auto map = stalled.next();
    ASSERT_TRUE(map.has_value());
    EXPECT_GT(map->header().epoch(), last_epoch);
    last_epoch = map->header().epoch();
    ++received;
  }
  EXPECT_EQ(last_epoch, E(kPublished - 1));
}

TEST(AggregatorService, SubscribersBeyondTheBoundAreRefusedCountedAndExported) {
  Metrics metrics("", "merge-aggregator", "sink");
  FakeClock clock(at(1, 5));
  AggregatorConfig config = rootConfig(Mode::kMadc, {1});
  config.admission.max_subscribers = 2;
  AggregatorServer server(std::move(config), clock, "", &metrics);
  ASSERT_TRUE(server.started());
  auto global_stub = server.globalStub();
  auto first = std::make_unique<Subscription>(*global_stub, false);
  Subscription second(*global_stub, false);
  ASSERT_TRUE(eventually([&] { return server.globalMaps().subscriberCount() == 2; }));
  {
    Subscription third(*global_stub, false);
    EXPECT_FALSE(third.next().has_value());
    const grpc::Status status = third.finish();
    EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << status.error_message();
    EXPECT_NE(status.error_message().find("max_subscribers"), std::string::npos) << status.error_message();
  }
  EXPECT_EQ(server.globalMaps().refusedSubscribers(), 1U);
  EXPECT_EQ(counterValue(metrics, "fogmap_subscribers_refused_total", {}), 1.0);
  // A subscriber that leaves frees its place; the two served still get every map.
  first.reset();
  ASSERT_TRUE(eventually([&] { return server.globalMaps().subscriberCount() == 1; }));
  Subscription fourth(*global_stub, false);
  ASSERT_TRUE(eventually([&] { return server.globalMaps().subscriberCount() == 2; }));
  GlobalMapMessage global;
  global.header.node = kRoot;
  global.header.epoch = E(1);
  server.globalMaps().publish(global);
  for (Subscription* s : {&second, &fourth}) {
    const auto map = s->next();
    ASSERT_TRUE(map.has_value());
    EXPECT_EQ(map->header().epoch(), E(1));
  }
  EXPECT_EQ(server.globalMaps().refusedSubscribers(), 1U);
}

TEST(AggregatorService, DrainAtShutdownPublishesEveryOpenEpoch) {
  FakeClock clock(at(1, 5));
  AggregatorServer server(rootConfig(Mode::kMadc, {1, 2}), clock);
  ASSERT_TRUE(server.started());
  auto global_stub = server.globalStub();
  Subscription subscription(*global_stub, false);
  ASSERT_TRUE(eventually([&] { return server.globalMaps().subscriberCount() == 1; }));
  std::mt19937_64 rng(37);
  auto stub = server.ingestStub();
  Child a(*stub);
  Child b(*stub);
  ASSERT_TRUE(a.writeMap(1, randomMap(rng, 1, E(2), 2)));  // epoch 2 has not begun
  ASSERT_TRUE(a.answered(1));
  ASSERT_TRUE(b.writeMap(1, randomMap(rng, 2, E(1), 2)));  // epoch 1 waits for child 1
  ASSERT_TRUE(b.answered(1));
  EXPECT_EQ(server.emitter().pollOnce(), 0U);
  server.ingest().stopAccepting();
  ASSERT_TRUE(a.writeMap(2, randomMap(rng, 1, E(1), 2)));
  EXPECT_FALSE(a.readAck().has_value()) << "after stopAccepting nothing is answered";
  EXPECT_EQ(a.finish().error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_EQ(server.emitter().drain(), 2U) << "nothing acknowledged is abandoned";
  for (const std::uint64_t epoch : {E(1), E(2)}) {
    const auto map = subscription.next();
    ASSERT_TRUE(map.has_value());
    EXPECT_EQ(map->header().epoch(), epoch);
  }
  (void)b.finish();
}

TEST(AggregatorService, BaselineSubscribersGetPointLabelsOnlyWhenTheyAskForThem) {
  FakeClock clock(at(5, 5));
  AggregatorServer server(rootConfig(Mode::kBaseline, {1, 2}), clock);
  ASSERT_TRUE(server.started());
  auto global_stub = server.globalStub();
  Subscription with_labels(*global_stub, true);
  Subscription without_labels(*global_stub, false);
  ASSERT_TRUE(eventually([&] { return server.globalMaps().subscriberCount() == 2; }));

  std::mt19937_64 rng(34);
  auto ingest_stub = server.ingestStub();
  Child a(*ingest_stub);
  Child b(*ingest_stub);
  std::uint64_t sequence = 0;
  // Sensor 2's first blob overlaps sensor 1's last one.
  for (const auto& chunk : scanChunks(rng, 1, E(5), 0.0F)) ASSERT_TRUE(a.writePoints(++sequence, chunk));
  for (const auto& chunk : scanChunks(rng, 2, E(5), 8.0F)) ASSERT_TRUE(b.writePoints(++sequence, chunk));
  EXPECT_TRUE(a.answered(1));
  EXPECT_TRUE(a.answered(2));
  EXPECT_TRUE(b.answered(3));
  EXPECT_TRUE(b.answered(4));

  // The poll is fired by hand: every upload is answered, so the epoch is complete now.
  ASSERT_EQ(server.emitter().pollOnce(), 1U);
  const auto labelled = with_labels.next();
  const auto plain = without_labels.next();
  ASSERT_TRUE(labelled.has_value());
  ASSERT_TRUE(plain.has_value());
  EXPECT_EQ(labelled->mode(), "baseline");
  EXPECT_EQ(objectCount(*labelled), 5U) << "six blobs, two of which coincide";
  EXPECT_EQ(objectCount(*plain), 5U);
  ASSERT_EQ(labelled->point_labels_size(), 2);
  EXPECT_EQ(labelled->point_labels(0).labels().size(), 75U * 4U);
  EXPECT_EQ(plain->point_labels_size(), 0);

  EXPECT_TRUE(a.finish().ok());
  EXPECT_TRUE(b.finish().ok());
}

TEST(AggregatorService, GeofencesAreSetAndQueriedOverGrpc) {
  FakeClock clock(at(8, 5));
  AggregatorServer server(rootConfig(Mode::kMadc, {1}), clock);
  ASSERT_TRUE(server.started());
  auto global_stub = server.globalStub();

  grpc::ClientContext invalid_context;
  v1::SetGeofenceReply reply;
  v1::Geofence empty;
  empty.set_name("empty");
  EXPECT_EQ(global_stub->SetGeofence(&invalid_context, empty, &reply).error_code(), grpc::StatusCode::INVALID_ARGUMENT);

  grpc::ClientContext set_context;
  ASSERT_TRUE(global_stub->SetGeofence(&set_context, toProto(boxGeofence("zone", {-2, -2, -2}, {2, 2, 2})), &reply).ok());
  EXPECT_EQ(reply.geofence_count(), 1U);

  auto ingest_stub = server.ingestStub();
  Child child(*ingest_stub);
  MapMessage map;
  map.header.node = 1;
  map.header.epoch = E(8);
  map.header.sensor_time_ns = kT0;
  map.header.contributing_nodes = {1};
  Ellipsoid near;
  near.id = {1, E(8), 0};
  near.center = {0.0, 0.0, 0.0};
  near.shape = Eigen::Matrix3d::Identity() * 0.25;
  near.point_count = 12;
  Ellipsoid far = near;
  far.id = {1, E(8), 1};
  far.center = {20.0, 0.0, 0.0};
  // A lone fragment inside the zone (fewer than min_points points, joined to nothing): not an
  // object of the published map, so no intrusion.
  Ellipsoid fragment = near;
  fragment.id = {1, E(8), 2};
  fragment.center = {1.5, 1.5, 0.0};
  fragment.point_count = 3;
  map.map = localMap({near, far, fragment});
  ASSERT_TRUE(child.writeMap(1, map));
  ASSERT_TRUE(child.answered(1));
  ASSERT_EQ(server.emitter().pollOnce(), 1U);

  grpc::ClientContext query_context;
  v1::GeofenceQuery query;
  query.set_name("zone");
  v1::GeofenceReport report;
  ASSERT_TRUE(global_stub->QueryGeofences(&query_context, query, &report).ok());
  EXPECT_EQ(report.epoch(), E(8));
  ASSERT_EQ(report.intrusions_size(), 1);
  EXPECT_EQ(report.intrusions(0).geofence(), "zone");
  EXPECT_EQ(report.intrusions(0).object_index(), 0U);
  EXPECT_EQ(report.intrusions(0).containment(), v1::CONTAINMENT_INSIDE);
  ASSERT_EQ(report.intrusions(0).ellipsoids_size(), 1);
  EXPECT_EQ(report.intrusions(0).ellipsoids(0).index(), 0U);

  grpc::ClientContext missing_context;
  query.set_name("nowhere");
  EXPECT_EQ(global_stub->QueryGeofences(&missing_context, query, &report).error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_TRUE(child.finish().ok());
}

TEST(AggregatorService, ExtTreeMergesAtTheIntermediateAndRelaysPointsToTheRoot) {
  // sink (100) <- agg (101) <- edges 1, 2; edge 3 belongs directly to the sink but never connects.
  FakeClock clock(at(1, 5));
  AggregatorConfig root_config = rootConfig(Mode::kExt, {});
  root_config.levels = 2;
  root_config.children = {{101, {1, 2}, "agg-101"}, {3, {3}, "edge-3"}};
  AggregatorServer root(root_config, clock);
  ASSERT_TRUE(root.started());
  root.emitter().start();
  auto global_stub = root.globalStub();
  Subscription subscription(*global_stub, true);
  ASSERT_TRUE(eventually([&] { return root.globalMaps().subscriberCount() == 1; }));

  AggregatorConfig mid_config = rootConfig(Mode::kExt, {1, 2});
  mid_config.node = 101;
  mid_config.is_root = false;
  AggregatorServer mid(mid_config, clock, root.target());
  ASSERT_TRUE(mid.started());
  mid.emitter().start();

  std::mt19937_64 rng(35);
  const MadcParams params;
  const std::vector<Cloud> clouds{blobRow(rng, 0.0F), blobRow(rng, 8.0F)};  // blob at x = 8 seen by both
  auto stub = mid.ingestStub();
  Child a(*stub);
  Child b(*stub);
  Child* edges[2] = {&a, &b};
  // Epoch 1 makes both edges live at the intermediate; a relayed chunk is the first thing the
  // root sees, so the root must name the intermediate's stream by the sensor's id. A relayed
  // chunk is answered when the root has answered it.
  for (std::uint32_t s = 0; s < 2; ++s) {
    const auto local = genLocalMap(clouds[s], s + 1, E(1), params).value();
    ASSERT_TRUE(edges[s]->writePoints(1, wholeScan(s + 1, E(1), clouds[s], local.clustering.labels)));
    ASSERT_TRUE(edges[s]->answered(1));
    MapMessage map = randomMap(rng, s + 1, E(1), 0);
    map.map = local.map;
    ASSERT_TRUE(edges[s]->writeMap(2, map));
    const auto ack = edges[s]->readAck();
    ASSERT_TRUE(ack.has_value());
    EXPECT_NE(ack->status(), v1::ACK_STATUS_REFUSED) << ack->reason();
  }
  clock.set(at(2, 5));
  std::vector<LocalMapResult> locals;
  std::vector<Map> maps;
  for (std::uint32_t s = 0; s < 2; ++s) {
    locals.push_back(genLocalMap(clouds[s], s + 1, E(2), params).value());
    MapMessage map = randomMap(rng, s + 1, E(2), 0);
    map.map = locals.back().map;
    maps.push_back(overTheWire(map));
    ASSERT_TRUE(edges[s]->writeMap(3, map));
    ASSERT_TRUE(edges[s]->writePoints(4, wholeScan(s + 1, E(2), clouds[s], locals.back().clustering.labels)));
    ASSERT_TRUE(edges[s]->answered(3));
    ASSERT_TRUE(edges[s]->answered(4));
  }

  std::optional<GlobalMapMessage> received;
  for (int i = 0; i < 4 && !received; ++i) {  // epoch 1 (and perhaps a revision), then epoch 2
    const auto proto = subscription.next();
    ASSERT_TRUE(proto.has_value()) << "the subscription ended before epoch 2";
    auto converted = fromProto(*proto);
    ASSERT_TRUE(converted.ok()) << converted.error().message;
    if (converted->header.epoch == E(2)) received = std::move(*converted);
  }
  ASSERT_TRUE(received.has_value());
  const Map expected = overTheWire(mergeAll(maps).map);
  EXPECT_EQ(received->map, expected);
  EXPECT_EQ(received->header.contributing_nodes, (std::vector<std::uint32_t>{1, 2}));
  EXPECT_EQ(received->header.missing_nodes, (std::vector<std::uint32_t>{3}));
  ASSERT_EQ(received->point_labels.size(), 2U);
  for (std::uint32_t s = 0; s < 2; ++s) {
    const auto& labels = received->point_labels[s].labels;
    ASSERT_EQ(labels.size(), clouds[s].size());
    for (std::size_t i = 0; i < labels.size(); ++i) {
      const std::int32_t local = locals[s].clustering.labels[i];
      if (local < 0) {
        EXPECT_EQ(labels[i], -1);
        continue;
      }
      ASSERT_GE(labels[i], 0);
      ASSERT_LT(static_cast<std::size_t>(labels[i]), expected.objects.size());
      const auto& ellipsoids = expected.objects[static_cast<std::size_t>(labels[i])].ellipsoids;
      const EllipsoidId id{s + 1, E(2), static_cast<std::uint32_t>(local)};
      EXPECT_TRUE(std::any_of(ellipsoids.begin(), ellipsoids.end(), [&](const Ellipsoid& e) { return e.id == id; }));
    }
  }
  EXPECT_EQ(root.core([](MergeAggregator& core) { return core.liveChildren(at(2, 5)); }), 1U)
      << "the intermediate's one stream, named by a relayed chunk and by its own maps";
  EXPECT_TRUE(a.finish().ok());
  EXPECT_TRUE(b.finish().ok());
}

TEST(AggregatorService, RelayedChunkCarriesTheRootsAnswerBackToTheEdge) {
  // The root's clock is a second ahead of the intermediate's: the intermediate takes the chunk,
  // the root refuses it as clock skew, and the edge hears the root's refusal (an intermediate
  // never answers for data it has only queued).
  FakeClock root_clock(at(11, 0));
  FakeClock mid_clock(at(1, 5));
  AggregatorConfig root_config = rootConfig(Mode::kBaseline, {});
  root_config.levels = 2;
  root_config.children = {{101, {1}, "agg-101"}};
  AggregatorServer root(root_config, root_clock);
  ASSERT_TRUE(root.started());
  AggregatorConfig mid_config = rootConfig(Mode::kBaseline, {1});
  mid_config.node = 101;
  mid_config.is_root = false;
  AggregatorServer mid(mid_config, mid_clock, root.target());
  ASSERT_TRUE(mid.started());

  std::mt19937_64 rng(38);
  auto stub = mid.ingestStub();
  Child edge(*stub);
  const auto chunks = scanChunks(rng, 1, E(1), 0.0F);
  ASSERT_TRUE(edge.writePoints(1, chunks[0]));
  const auto refused = edge.readAck();
  ASSERT_TRUE(refused.has_value());
  EXPECT_EQ(refused->sequence(), 1U);
  EXPECT_EQ(refused->status(), v1::ACK_STATUS_REFUSED);
  EXPECT_NE(refused->reason().find("admission window"), std::string::npos) << refused->reason();
  EXPECT_EQ(mid.core([](MergeAggregator& core) { return core.counters().relayed; }), 1U);
  EXPECT_EQ(root.core([](MergeAggregator& core) { return core.counters().refused.at(Refusal::kClockSkew); }), 1U);

  root_clock.set(at(1, 5));  // clocks agree again: the next chunk reaches the root and is applied
  ASSERT_TRUE(edge.writePoints(2, chunks[1]));
  EXPECT_TRUE(edge.answered(2));
  EXPECT_TRUE(edge.finish().ok());
}

}  // namespace
}  // namespace fogmap
