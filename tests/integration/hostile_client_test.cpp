// Integration: a hostile (or broken) client attacks a running root over gRPC while three honest
// edges replay the bundled KITTI frames. The root must keep publishing every period with the
// honest data, answer geofences on current epochs, refuse every attack with its reason and gRPC
// code, and count it by reason.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "common/base/clock.hpp"
#include "common/base/epochs.hpp"
#include "common/config/topology_presets.hpp"
#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/grpc_options.hpp"
#include "services/common/proto_convert.hpp"
#include "tests/support/cluster_control.hpp"
#include "tests/support/free_ports.hpp"
#include "harness/cluster_run.hpp"
#include "harness/launcher.hpp"
#include "tests/support/source_dir.hpp"

namespace fogmap {
namespace {

using namespace std::chrono_literals;

constexpr std::uint32_t kHonestEdges = 3;
// The attacker's stream lasts this long at most, and the root's admission window is as wide: an
// epoch taken from the clock (or from a map the root just published) while the stream is open is
// still inside the window when the root reads the upload, however slow the machine, and an epoch
// meant to be outside lies a whole window beyond it.
constexpr std::chrono::seconds kAttackTime{60};

using test_support::kittiSequenceDir;

// The value of `family{...reason="reason"...}` in a Prometheus text page (0 when absent).
double refusedCount(const std::string& page, const std::string& reason) {
  std::istringstream lines(page);
  std::string line;
  double total = 0.0;
  while (std::getline(lines, line)) {
    if (line.rfind("fogmap_refused_uploads_total{", 0) != 0) continue;
    if (line.find("reason=\"" + reason + "\"") == std::string::npos) continue;
    total += std::strtod(line.substr(line.rfind(' ') + 1).c_str(), nullptr);
  }
  return total;
}

Ellipsoid ball(std::uint32_t node, std::uint64_t epoch, std::uint32_t index, const Eigen::Vector3d& centre) {
  Ellipsoid e;
  e.id = {node, epoch, index};
  e.center = centre;
  e.shape = Eigen::Matrix3d::Identity() * 0.25;
  e.point_count = 10;
  return e;
}

// `wire` kExact where an attack edits an ellipsoid's fields on the wire.
v1::Upload mapUpload(std::uint32_t node, std::uint64_t epoch, std::vector<Ellipsoid> ellipsoids,
                     EllipsoidWire wire = EllipsoidWire::kCompact) {
  MapMessage message;
  message.header.node = node;
  message.header.epoch = epoch;
  message.header.sensor_time_ns = systemNowNs();
  message.header.contributing_nodes = {node};
  message.map = localMap(std::move(ellipsoids));
  v1::Upload upload;
  *upload.mutable_map() = toProto(message, wire);
  return upload;
}

// The attacker: one stream to the root that claims to be edge 1, written and answered in lock step.
class Attacker {
 public:
  explicit Attacker(const std::string& target) : channel_(makeChannel(target, 256U << 20)) {
    stub_ = v1::MapIngest::NewStub(channel_);
    context_.set_deadline(std::chrono::system_clock::now() + kAttackTime);
    stream_ = stub_->Push(&context_);
  }
  // Sends one upload under `sequence` and returns the root's answer (nullopt: the stream ended).
  std::optional<v1::Ack> send(std::uint64_t sequence, v1::Upload upload) {
    upload.set_sequence(sequence);
    if (!stream_->Write(upload)) return std::nullopt;
    v1::Ack ack;
    if (!stream_->Read(&ack)) return std::nullopt;
    return ack;
  }
  grpc::Status finish() {
    stream_->WritesDone();
    return stream_->Finish();
  }

 private:
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::MapIngest::Stub> stub_;
  grpc::ClientContext context_;
  std::unique_ptr<grpc::ClientReaderWriter<v1::Upload, v1::Ack>> stream_;
};

bool allHonestEdges(const GlobalMapMessage& global) {
  return global.header.contributing_nodes.size() == kHonestEdges;
}

TEST(HostileClient, RootKeepsPublishingHonestDataAndCountsEveryAttack) {
  TopologyConfig t = makeStarTopology(kHonestEdges, kittiSequenceDir(), 40000);
  test_support::useFreePorts(t);
  t.name = "hostile";
  t.deadline_ms = 500.0;  // a loaded CI machine must not turn slow epochs into partial ones
  t.admission.window_periods = std::chrono::duration<double, std::milli>(kAttackTime).count() / t.period_ms;
  test_support::replayUntilStopped(t);  // the attacks take as long as they take; the edges go on
  const NodeConfig& root = *t.root();
  const std::string target = endpoint(root.host, root.port);
  const auto schedule = EpochSchedule::create(t.period_ms, t.deadline_ms);
  ASSERT_TRUE(schedule.ok());
  const auto now_epoch = [&] { return schedule->epochAt(systemNowNs()); };
  const auto window_epochs = static_cast<std::uint64_t>(std::llround(t.admission.window_periods));

  std::optional<v1::GeofenceReport> geofences;
  std::uint64_t published_before_query = 0;
  std::uint64_t epoch_after_query = 0;
  std::string metrics_page;
  std::map<std::string, std::string> edge_pages;  // each honest edge's /metrics after the attacks
  std::uint64_t attack_start_epoch = 0;
  std::uint64_t attack_end_epoch = 0;
  std::string answers;  // what the root said to each attack, for the failure messages
  harness::RunOptions options;
  options.frames = std::numeric_limits<std::uint64_t>::max();  // every epoch until the edges are stopped
  options.timeout = 3 * kAttackTime;
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("fogmap-it-" + std::to_string(::getpid()) + "-hostile");
  std::filesystem::create_directories(dir);
  const auto result = harness::runCluster(dir, t, options, [&](const harness::Cluster& cluster) {
    const test_support::EdgesStopper stop_edges(cluster, t);  // when the attacks are over
    // Once the root has published a map with every honest edge, attack on one stream that claims
    // to be edge 1.
    test_support::RootSubscription published(t, options.timeout);
    const auto started = published.readUntil(allHonestEdges);
    ASSERT_TRUE(started.has_value()) << "no global map with every honest edge before the attacks";
    attack_start_epoch = started->header.epoch;
    Attacker attacker(target);
    std::uint64_t sequence = 1;
    // Refused with the reason and gRPC code of the rule: INVALID_ARGUMENT, RESOURCE_EXHAUSTED for
    // a size bound.
    const auto expect_refused = [&](v1::Upload upload, const std::string& what,
                                    grpc::StatusCode code = grpc::StatusCode::INVALID_ARGUMENT) {
      const auto ack = attacker.send(sequence++, std::move(upload));
      ASSERT_TRUE(ack.has_value()) << what << ": the root closed the stream";
      EXPECT_EQ(ack->status(), v1::ACK_STATUS_REFUSED) << what << ": " << ack->reason();
      EXPECT_EQ(ack->code(), static_cast<int>(code)) << what << ": " << ack->reason();
      EXPECT_FALSE(ack->reason().empty()) << what;
      if (what != "flood") answers += what + ": " + ack->reason() + "\n";
    };
    // 1. A map ahead of the root's clock, which used to open that epoch early and publish it
    //    forged: three windows ahead, it stays beyond the window longer than the stream lasts.
    const std::uint64_t ahead = now_epoch() + 3 * window_epochs;
    expect_refused(mapUpload(1, ahead, {ball(1, ahead, 500, {0, 0, 0})}), "epoch beyond the window ahead");
    // 2. The last epoch there is, which used to freeze the geofences on it.
    const std::uint64_t last = std::numeric_limits<std::uint64_t>::max();
    expect_refused(mapUpload(1, last, {ball(1, last, 500, {0, 0, 0})}), "epoch 2^64 - 1");
    expect_refused(mapUpload(1, 1ULL << 63, {ball(1, 1ULL << 63, 500, {0, 0, 0})}), "epoch 2^63");
    expect_refused(mapUpload(1, 0, {ball(1, 0, 500, {0, 0, 0})}), "epoch 0");
    // 3. A flood of distinct epochs near 2^62, which used to jam the closed-epoch history.
    for (std::uint64_t i = 0; i < 5000 && !::testing::Test::HasFailure(); ++i) {
      const std::uint64_t epoch = (1ULL << 62) + i;
      expect_refused(mapUpload(1, epoch, {ball(1, epoch, 500, {0, 0, 0})}), "flood");
    }
    // 4. Forged node ids: a map that says it is edge 2's, and edge 1's map carrying edge 2's ellipsoid.
    const std::uint64_t next = now_epoch() + 1;
    expect_refused(mapUpload(2, next, {ball(2, next, 500, {0, 0, 0})}), "map of another node");
    expect_refused(mapUpload(1, next, {ball(2, next, 500, {0, 0, 0})}), "ellipsoid of another node");
    // 5. Oversized and absurd maps: 1,000,000 ellipsoids (~54 MB, under the transport limit),
    //    a centre at 1e30, a shape of condition 1e60.
    {
      v1::Upload huge = mapUpload(1, next, {ball(1, next, 500, {0, 0, 0})}, EllipsoidWire::kExact);
      v1::MapObject* object = huge.mutable_map()->mutable_objects(0);
      const v1::Ellipsoid one = object->ellipsoids(0);
      for (std::uint32_t k = 1; k < 1'000'000; ++k) {
        v1::Ellipsoid* e = object->add_ellipsoids();
        *e = one;
        e->mutable_id()->set_index(500 + k);
      }
      expect_refused(std::move(huge), "1,000,000 ellipsoids", grpc::StatusCode::RESOURCE_EXHAUSTED);
    }
    const std::uint64_t soon = now_epoch() + 1;  // building the huge map took a while
    expect_refused(mapUpload(1, soon, {ball(1, soon, 500, {1e30, 0, 0})}), "centre at 1e30");
    Ellipsoid needle = ball(1, soon, 500, {0, 0, 0});
    needle.shape = Eigen::Vector3d(1e30, 1e-30, 1e-30).asDiagonal();
    expect_refused(mapUpload(1, soon, {needle}), "condition 1e60");
    //    Values that do not convert: a shape that is not positive definite, a NaN centre.
    {
      v1::Upload indefinite = mapUpload(1, soon, {ball(1, soon, 500, {0, 0, 0})}, EllipsoidWire::kExact);
      indefinite.mutable_map()->mutable_objects(0)->mutable_ellipsoids(0)->mutable_shape()->Set(0, -0.25F);
      expect_refused(std::move(indefinite), "shape not positive definite");
      v1::Upload nan = mapUpload(1, soon, {ball(1, soon, 500, {0, 0, 0})}, EllipsoidWire::kExact);
      nan.mutable_map()->mutable_objects(0)->mutable_ellipsoids(0)->mutable_center()->Set(
          2, std::numeric_limits<float>::quiet_NaN());
      expect_refused(std::move(nan), "NaN centre");
    }
    // 6. Duplicates with other content, on the first epoch from now on that the root publishes:
    //    it was emitted, so whatever is applied to it is a late revision that never replaces the
    //    live picture.
    const std::uint64_t from = now_epoch();
    const auto emitted = published.readUntil([&](const GlobalMapMessage& g) { return g.header.epoch >= from; });
    ASSERT_TRUE(emitted.has_value()) << "the root stopped publishing during the attacks";
    const std::uint64_t past = emitted->header.epoch;
    const std::uint64_t reused = sequence++;
    const auto first = attacker.send(reused, mapUpload(1, past, {}));
    ASSERT_TRUE(first.has_value());
    EXPECT_EQ(first->status(), v1::ACK_STATUS_LATE) << first->reason();
    const auto conflict = attacker.send(reused, mapUpload(1, past, {ball(1, past, 900, {40, 0, 0})}));
    ASSERT_TRUE(conflict.has_value());
    EXPECT_EQ(conflict->status(), v1::ACK_STATUS_REFUSED) << "same sequence, other content";
    //    An ellipsoid id merged into that epoch, sent again with other geometry.
    const auto own = attacker.send(sequence++, mapUpload(1, past, {ball(1, past, 901, {60, 0, 0})}));
    ASSERT_TRUE(own.has_value());
    EXPECT_EQ(own->status(), v1::ACK_STATUS_LATE) << own->reason();
    expect_refused(mapUpload(1, past, {ball(1, past, 901, {-300, 300, 0})}), "same ellipsoid id, other geometry");
    EXPECT_TRUE(attacker.finish().ok());
    // 7. A stream from a node that is in no topology: answered REFUSED, then ended.
    {
      Attacker stranger(target);
      const auto ack = stranger.send(1, mapUpload(77, now_epoch(), {ball(77, now_epoch(), 500, {0, 0, 0})}));
      ASSERT_TRUE(ack.has_value()) << "unknown node: unanswered";
      EXPECT_EQ(ack->status(), v1::ACK_STATUS_REFUSED);
      EXPECT_EQ(ack->code(), static_cast<int>(grpc::StatusCode::INVALID_ARGUMENT)) << ack->reason();
      answers += "unknown node: " + ack->reason() + "\n";
      EXPECT_EQ(stranger.finish().error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    }
    attack_end_epoch = now_epoch();
    // The root goes on publishing the honest edges' maps after the attacks.
    const auto after = published.readUntil(
        [&](const GlobalMapMessage& g) { return g.header.epoch > attack_end_epoch && allHonestEdges(g); });
    ASSERT_TRUE(after.has_value()) << "nothing with every honest edge was published after the attacks";
    for (const auto& n : t.nodes) {
      if (n.role != Role::kEdge) continue;
      const auto page = harness::httpGet(n.host, n.metrics_port, "/metrics", 2000ms);
      ASSERT_TRUE(page.ok()) << n.name << ": " << page.error().message;
      edge_pages[n.name] = *page;
    }

    // Geofences answer on a current epoch: the root's latest map, at least the one just seen.
    auto channel = makeChannel(target, 64U << 20);
    auto global = v1::GlobalMapService::NewStub(channel);
    grpc::ClientContext set_context;
    set_context.set_deadline(std::chrono::system_clock::now() + 10s);
    v1::SetGeofenceReply reply;
    ASSERT_TRUE(global->SetGeofence(&set_context, toProto(boxGeofence("front", {0, -4, -3}, {20, 4, 3})), &reply).ok());
    published_before_query = after->header.epoch;
    grpc::ClientContext query_context;
    query_context.set_deadline(std::chrono::system_clock::now() + 10s);
    v1::GeofenceQuery query;
    v1::GeofenceReport report;
    ASSERT_TRUE(global->QueryGeofences(&query_context, query, &report).ok());
    epoch_after_query = now_epoch();
    geofences = report;

    const auto page = harness::httpGet(root.host, root.metrics_port, "/metrics", 2000ms);
    ASSERT_TRUE(page.ok()) << page.error().message;
    metrics_page = *page;
  });
  ASSERT_TRUE(result.ok()) << result.error().message;

  // Every attack shows in its counter.
  SCOPED_TRACE("the root's answers:\n" + answers);
  EXPECT_GE(refusedCount(metrics_page, "clock_skew"), 5004.0);
  EXPECT_GE(refusedCount(metrics_page, "malformed"), 2.0);
  EXPECT_GE(refusedCount(metrics_page, "unknown_node"), 1.0);
  EXPECT_GE(refusedCount(metrics_page, "forged_node"), 2.0);
  EXPECT_GE(refusedCount(metrics_page, "too_large"), 1.0);
  EXPECT_GE(refusedCount(metrics_page, "out_of_world"), 1.0);
  EXPECT_GE(refusedCount(metrics_page, "bad_shape"), 1.0);
  EXPECT_GE(refusedCount(metrics_page, "sequence_conflict"), 1.0);
  EXPECT_GE(refusedCount(metrics_page, "ellipsoid_conflict"), 1.0);

  // Geofences answered on the current epoch, not on a forged one: no older than the last map
  // published before the query, none that had not begun when the answer came.
  ASSERT_TRUE(geofences.has_value());
  EXPECT_LE(geofences->epoch(), epoch_after_query) << "the geofences answered on an epoch of the future";
  EXPECT_GE(geofences->epoch(), published_before_query) << "the geofences answered on an old epoch";

  // The root published every period, on time, with the honest edges' data.
  ASSERT_FALSE(result->epochs.empty());
  const std::uint64_t first = result->epochs.begin()->first;
  const std::uint64_t last = result->epochs.rbegin()->first;
  EXPECT_GT(last, attack_end_epoch) << "nothing was published after the attacks";
  // Every epoch, none skipped: an epoch the root could not publish on time (its emitter starved,
  // e.g. while it parsed the 54 MB upload on a busy machine) comes late, flagged, never left out.
  EXPECT_EQ(result->epochs.size(), last - first + 1) << "epochs were skipped between " << first << " and " << last;
  // While the attacks ran, the honest edges' maps were applied: the root answered every one of them
  // APPLIED or LATE, none was refused or dropped. (Whether a map came in time for its epoch's first
  // publication is the machine's speed: a starved edge skips epochs by design, docs/design.md.)
  ASSERT_EQ(edge_pages.size(), kHonestEdges);
  for (const auto& [name, page] : edge_pages) {
    EXPECT_EQ(harness::sumMetric(page, "fogmap_uploads_refused_by_parent_total"), 0.0) << name << "'s maps were refused";
    EXPECT_EQ(harness::sumMetric(page, "fogmap_dropped_uploads_total"), 0.0) << name << "'s maps were dropped";
    EXPECT_GT(harness::sumMetric(page, "fogmap_frames_total"), 0.0) << name;
  }
  std::size_t during_attacks = 0;
  std::size_t complete = 0;
  std::size_t late = 0;
  for (const auto& [epoch, global] : result->epochs) {
    // Late means published more than a period after the epoch's deadline, nothing else.
    const std::int64_t due = schedule->deadlineNs(epoch, 1) + schedule->periodNs();
    if (global.late) {
      ++late;
      EXPECT_GT(global.published_time_ns, due) << "epoch " << epoch << " flagged late, but published in time";
    }
    for (const auto& object : global.map.objects) {
      for (const auto& e : object.ellipsoids) {
        EXPECT_LT(e.id.index, 500U) << "an attacker's ellipsoid in epoch " << epoch;
        EXPECT_EQ(e.id.frame, epoch) << "an ellipsoid of another epoch in epoch " << epoch;
      }
    }
    if (epoch < attack_start_epoch || epoch > attack_end_epoch) continue;
    ++during_attacks;
    if (allHonestEdges(global)) ++complete;
  }
  EXPECT_GT(during_attacks, 0U);
  std::printf("epochs %lu..%lu under attack: %zu published, %zu of them with every honest edge; %zu of %zu "
              "epochs published late\n",
              static_cast<unsigned long>(attack_start_epoch), static_cast<unsigned long>(attack_end_epoch),
              during_attacks, complete, late, result->epochs.size());
}

}  // namespace
}  // namespace fogmap
