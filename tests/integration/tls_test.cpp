// Integration: a tree of real edge-cluster and merge-aggregator processes on 127.0.0.1 with mutual
// TLS on every link (certificates made at test time), replaying the bundled KITTI frames, while
// clients without a valid certificate, with a certificate that names no child, with a child's
// certificate speaking for another node, and without the right to set geofences go at the root.
// None of their messages may be applied, and the honest data must be applied every epoch.
#include <sys/stat.h>

#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "common/certs/certs.hpp"
#include "common/base/clock.hpp"
#include "common/base/epochs.hpp"
#include "common/config/topology_presets.hpp"
#include "common/geometry/geofence.hpp"
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
namespace fs = std::filesystem;

// The attackers' ellipsoids carry indices from here: the edges' own stay far below.
constexpr std::uint32_t kAttackIndex = 500;
// The attacks last this many epochs at least, in at most this many rounds.
constexpr std::uint64_t kAttackEpochs = 20;
constexpr int kMaxRounds = 200;
// An upload stream lasts this long at most, and the root's admission window is as wide: an epoch
// an attack takes from the clock is still inside the window when the root reads it, however slow
// the machine, so each attack is refused by its own rule and never as clock skew.
constexpr std::chrono::seconds kStreamTime{30};

using test_support::kittiSequenceDir;

// The sum of `family` samples whose labels contain `label` (every sample when empty) on a
// Prometheus text page.
double metricValue(const std::string& page, const std::string& family, const std::string& label = "") {
  std::istringstream lines(page);
  std::string line;
  double total = 0.0;
  while (std::getline(lines, line)) {
    if (line.rfind(family, 0) != 0 || line.size() <= family.size()) continue;
    if (line[family.size()] != '{' && line[family.size()] != ' ') continue;
    if (!label.empty() && line.find(label) == std::string::npos) continue;
    total += std::strtod(line.substr(line.rfind(' ') + 1).c_str(), nullptr);
  }
  return total;
}

void writePem(const fs::path& dir, const std::string& name, const PemPair& pair) {
  std::ofstream(dir / (name + ".crt")) << pair.cert;
  std::ofstream(dir / (name + ".key")) << pair.key;
  fs::permissions(dir / (name + ".key"), fs::perms::owner_read | fs::perms::owner_write);
}

// A map of `node` for `epoch` with one ellipsoid marked as the attacker's.
v1::Upload attackMap(std::uint32_t node, std::uint64_t epoch, std::uint32_t index) {
  Ellipsoid e;
  e.id = {node, epoch, kAttackIndex + index};
  e.center = {5.0, 0.0, 0.0};
  e.shape = Eigen::Matrix3d::Identity() * 0.25;
  e.point_count = 10;
  MapMessage message;
  message.header.node = node;
  message.header.epoch = epoch;
  message.header.sensor_time_ns = systemNowNs();
  message.header.contributing_nodes = {node};
  message.map = localMap({e});
  v1::Upload upload;
  *upload.mutable_map() = toProto(message);
  return upload;
}

// One upload stream, written and answered in lock step.
class Uploader {
 public:
  explicit Uploader(const std::shared_ptr<grpc::Channel>& channel) : stub_(v1::MapIngest::NewStub(channel)) {
    context_.set_deadline(std::chrono::system_clock::now() + kStreamTime);
    stream_ = stub_->Push(&context_);
  }
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
  std::unique_ptr<v1::MapIngest::Stub> stub_;
  grpc::ClientContext context_;
  std::unique_ptr<grpc::ClientReaderWriter<v1::Upload, v1::Ack>> stream_;
};

grpc::Status setGeofence(const std::shared_ptr<grpc::Channel>& channel, const std::string& name,
                         v1::SetGeofenceReply* reply) {
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + 10s);
  return v1::GlobalMapService::NewStub(channel)->SetGeofence(&context, toProto(boxGeofence(name, {0, -4, -3}, {20, 4, 3})),
                                                             reply);
}

grpc::Status queryGeofences(const std::shared_ptr<grpc::Channel>& channel, const std::string& name) {
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + 10s);
  v1::GeofenceQuery query;
  query.set_name(name);
  v1::GeofenceReport report;
  return v1::GlobalMapService::NewStub(channel)->QueryGeofences(&context, query, &report);
}

// A Subscribe call: the global maps as the root publishes them.
class Subscription {
 public:
  explicit Subscription(const std::shared_ptr<grpc::Channel>& channel) : stub_(v1::GlobalMapService::NewStub(channel)) {
    context_.set_deadline(std::chrono::system_clock::now() + 60s);
    v1::SubscribeRequest request;
    request.set_on_time_only(true);
    reader_ = stub_->Subscribe(&context_, request);
  }
  ~Subscription() { context_.TryCancel(); }
  // Reads global maps until one satisfies `done` (true) or the stream ends (false).
  template <class F>
  bool readUntil(F done) {
    v1::GlobalMap message;
    while (reader_->Read(&message)) {
      const auto global = fromProto(message);
      if (global.ok() && done(*global)) return true;
    }
    return false;
  }

 private:
  std::unique_ptr<v1::GlobalMapService::Stub> stub_;
  grpc::ClientContext context_;
  std::unique_ptr<grpc::ClientReader<v1::GlobalMap>> reader_;
};

TEST(MutualTls, OnlyTheHonestChildrensDataIsAppliedAndEveryAttemptIsTurnedAway) {
  // sink <- agg-1 <- edge-1, edge-2; sink <- edge-3. The root's children are agg-1 and edge-3.
  TopologyConfig t = makeTreeTopology(3, kittiSequenceDir(), 40000);
  test_support::useFreePorts(t);
  t.name = "tls-tree";
  t.deadline_ms = 500.0;  // a loaded CI machine must not turn slow epochs into partial ones
  t.admission.window_periods = std::chrono::duration<double, std::milli>(kStreamTime).count() / t.period_ms;
  test_support::replayUntilStopped(t);  // until the attacks are over, however long they take
  ASSERT_EQ(t.root()->name, "sink");
  ASSERT_NE(t.find("agg-1"), nullptr);
  ASSERT_EQ(t.find("edge-3")->parent, "sink");
  const std::vector<std::uint32_t> honest = t.sensorsBelow("sink");
  ASSERT_EQ(honest, (std::vector<std::uint32_t>{1, 2, 3}));

  const fs::path dir = fs::temp_directory_path() / ("fogmap-it-" + std::to_string(::getpid()) + "-tls");
  fs::remove_all(dir);
  const fs::path certs = dir / "certs";
  fs::create_directories(certs);
  const auto now = std::chrono::system_clock::now();
  const auto ca = makeCertificateAuthority("fogmap test CA", now - 72h, now + 24h);
  const auto wrong_ca = makeCertificateAuthority("fogmap test CA", now - 72h, now + 24h);  // same name, other key
  ASSERT_TRUE(ca.ok() && wrong_ca.ok());
  writePem(certs, "ca", *ca);
  const auto issue = [&](const PemPair& authority, const std::string& name, CertTime from, CertTime until) {
    auto pair = issueCertificate(authority, {name, {name}, {"127.0.0.1"}, from, until});
    EXPECT_TRUE(pair.ok()) << pair.error().message;
    return pair.ok() ? *pair : PemPair{};
  };
  for (const auto& n : t.nodes) writePem(certs, n.name, issue(*ca, n.name, now - 1h, now + 1h));
  for (const std::string client : {"operator", "intruder"}) writePem(certs, client, issue(*ca, client, now - 1h, now + 1h));
  t.tls = TlsConfig{certs / "ca.crt", certs, {"operator"}};

  const auto identity = [&](const std::string& name) {
    const auto pem = loadTls(t, name, now);
    EXPECT_TRUE(pem.ok() && pem->has_value()) << (pem.ok() ? "" : pem.error().message);
    return pem.ok() && pem->has_value() ? **pem : TlsPem{};
  };
  const TlsPem intruder = identity("intruder");
  const TlsPem edge1 = identity("edge-1");  // a node of the cluster, but a child of agg-1, not of the root
  const TlsPem edge3 = identity("edge-3");  // a child of the root
  const TlsPem op = identity("operator");
  TlsPem foreign = edge3;  // edge-3's name, from another CA
  const PemPair foreign_pair = issue(*wrong_ca, "edge-3", now - 1h, now + 1h);
  foreign.cert = foreign_pair.cert;
  foreign.key = foreign_pair.key;
  TlsPem expired = edge3;  // edge-3's name, from the right CA, expired yesterday
  const PemPair expired_pair = issue(*ca, "edge-3", now - 48h, now - 24h);
  expired.cert = expired_pair.cert;
  expired.key = expired_pair.key;
  grpc::SslCredentialsOptions no_certificate;
  no_certificate.pem_root_certs = ca->cert;

  const NodeConfig& root = *t.root();
  const std::string target = endpoint(root.host, root.port);
  const auto channel = [&](const std::shared_ptr<grpc::ChannelCredentials>& credentials) {
    return makeChannel(target, credentials, 64U << 20);
  };
  const auto schedule = EpochSchedule::create(t.period_ms, t.deadline_ms);
  ASSERT_TRUE(schedule.ok());
  const auto now_epoch = [&] { return schedule->epochAt(systemNowNs()); };

  std::uint64_t attack_start = 0;
  std::uint64_t attack_end = 0;
  std::uint64_t unknown_peer_uploads = 0;
  std::uint64_t forged_uploads = 0;
  std::uint64_t denied_geofences = 0;
  std::string metrics_page;
  std::map<std::string, std::string> sender_pages;  // each edge's and agg-1's /metrics after the attacks
  harness::RunOptions options;
  options.frames = std::numeric_limits<std::uint64_t>::max();  // everything the edges publish
  options.timeout = 120s;
  options.identity = "operator";
  const auto result = harness::runCluster(dir, t, options, [&](const harness::Cluster& cluster) {
    const test_support::EdgesStopper stop_edges(cluster, t);  // once the attacks are over
    // Subscribe is open to any certificate the CA issued: the intruder watches, and the attacks
    // start once a global map with every honest sensor came out.
    Subscription watch(channel(channelCredentials(intruder)));
    ASSERT_TRUE(watch.readUntil([&](const GlobalMapMessage& g) { return g.header.contributing_nodes == honest; }))
        << "no complete global map before the attacks";
    attack_start = now_epoch();

    // The attacks go on in rounds for kAttackEpochs epochs at least (bounded by kMaxRounds), so
    // that "applied every epoch throughout" covers many epochs; a round starts when the root has
    // published another global map since the last one.
    const std::vector<std::pair<std::string, std::shared_ptr<grpc::ChannelCredentials>>> strangers = {
        {"plaintext", grpc::InsecureChannelCredentials()},
        {"TLS without a client certificate", grpc::SslCredentials(no_certificate)},
        {"a certificate from another CA", channelCredentials(foreign)},
        {"an expired certificate from the right CA", channelCredentials(expired)},
    };
    for (int round = 0; round < kMaxRounds && !::testing::Test::HasFailure() &&
                        (round == 0 || now_epoch() < attack_start + kAttackEpochs);
         ++round) {
      SCOPED_TRACE("round " + std::to_string(round));
      // 1. No valid certificate: the handshake fails inside gRPC, before any handler runs, so the
      //    application has nothing to count; the calls fail UNAVAILABLE and nothing is answered.
      for (const auto& [what, credentials] : strangers) {
        SCOPED_TRACE(what);
        const auto stranger = channel(credentials);
        Uploader uploader(stranger);
        for (std::uint32_t k = 0; k < 3; ++k) {
          EXPECT_FALSE(uploader.send(k + 1, attackMap(3, now_epoch() + 1, k)).has_value()) << "an upload was answered";
        }
        EXPECT_FALSE(uploader.finish().ok());
        v1::SetGeofenceReply reply;
        EXPECT_EQ(setGeofence(stranger, "stranger", &reply).error_code(), grpc::StatusCode::UNAVAILABLE);
        EXPECT_EQ(queryGeofences(stranger, "").error_code(), grpc::StatusCode::UNAVAILABLE);
      }

      // 2. Valid certificates that name no child of the root: the intruder, and edge-1, which may
      //    speak only to agg-1. Every upload is refused as unknown_peer, whatever node it claims.
      for (const TlsPem* peer : {&intruder, &edge1}) {
        SCOPED_TRACE(peer->name);
        Uploader uploader(channel(channelCredentials(*peer)));
        for (std::uint32_t k = 0; k < 10; ++k) {
          const std::uint32_t claimed = k % 2 == 0 ? 3 : 1;
          const auto ack = uploader.send(k + 1, attackMap(claimed, now_epoch() + 1, k));
          ASSERT_TRUE(ack.has_value()) << "the root closed the stream";
          EXPECT_EQ(ack->status(), v1::ACK_STATUS_REFUSED) << ack->reason();
          EXPECT_EQ(ack->reason().rfind("unknown_peer: ", 0), 0U) << ack->reason();
          ++unknown_peer_uploads;
        }
        EXPECT_TRUE(uploader.finish().ok());
      }

      // 3. A child's own certificate speaking for another node (edge-3 claiming edge 1's maps, or
      //    carrying its ellipsoids): refused as forged_node. Its real stream goes on beside it.
      {
        Uploader uploader(channel(channelCredentials(edge3)));
        for (std::uint32_t k = 0; k < 10; ++k) {
          v1::Upload upload = attackMap(1, now_epoch() + 1, k);
          // Every other one with edge 3's own header around edge 1's ellipsoid.
          if (k % 2 == 1) upload.mutable_map()->mutable_header()->set_node(3);
          const auto ack = uploader.send(k + 1, std::move(upload));
          ASSERT_TRUE(ack.has_value()) << "the root closed the stream";
          EXPECT_EQ(ack->status(), v1::ACK_STATUS_REFUSED) << ack->reason();
          ++forged_uploads;
        }
        EXPECT_TRUE(uploader.finish().ok());
      }

      // 4. Geofences: only tls.geofence_clients (operator) may set them; anyone may query.
      for (const TlsPem* peer : {&intruder, &edge3}) {
        v1::SetGeofenceReply reply;
        const grpc::Status denied = setGeofence(channel(channelCredentials(*peer)), "forbidden", &reply);
        EXPECT_EQ(denied.error_code(), grpc::StatusCode::PERMISSION_DENIED)
            << peer->name << ": " << denied.error_message();
        ++denied_geofences;
        EXPECT_TRUE(queryGeofences(channel(channelCredentials(*peer)), "").ok()) << peer->name;
      }
      ASSERT_TRUE(watch.readUntil([](const GlobalMapMessage&) { return true; })) << "the root stopped publishing";
    }
    v1::SetGeofenceReply reply;
    const grpc::Status allowed = setGeofence(channel(channelCredentials(op)), "front", &reply);
    EXPECT_TRUE(allowed.ok()) << allowed.error_message();
    EXPECT_EQ(reply.geofence_count(), 1U) << "a denied geofence was set";
    EXPECT_EQ(queryGeofences(channel(channelCredentials(op)), "forbidden").error_code(), grpc::StatusCode::NOT_FOUND);
    attack_end = now_epoch();

    // The root goes on publishing after the attacks: wait for a complete map of a later epoch.
    EXPECT_TRUE(watch.readUntil([&](const GlobalMapMessage& g) {
      return g.header.epoch > attack_end && g.header.contributing_nodes == honest;
    })) << "nothing complete was published after the attacks";
    for (const auto& n : t.nodes) {
      if (n.name == root.name) continue;
      const auto sender = harness::httpGet(n.host, n.metrics_port, "/metrics", 2000ms);
      ASSERT_TRUE(sender.ok()) << n.name << ": " << sender.error().message;
      sender_pages[n.name] = *sender;
    }
    const auto page = harness::httpGet(root.host, root.metrics_port, "/metrics", 2000ms);
    ASSERT_TRUE(page.ok()) << page.error().message;
    metrics_page = *page;
  });
  ASSERT_TRUE(result.ok()) << result.error().message;
  ASSERT_GT(attack_end, attack_start);
  std::printf("attacks over epochs %lu..%lu: %lu uploads refused unknown_peer, %lu forged_node, %lu SetGeofence denied\n",
              static_cast<unsigned long>(attack_start), static_cast<unsigned long>(attack_end),
              static_cast<unsigned long>(unknown_peer_uploads), static_cast<unsigned long>(forged_uploads),
              static_cast<unsigned long>(denied_geofences));

  // Every refusal the application can see is counted, exactly.
  EXPECT_EQ(metricValue(metrics_page, "fogmap_refused_uploads_total", "reason=\"unknown_peer\""),
            static_cast<double>(unknown_peer_uploads));
  EXPECT_EQ(metricValue(metrics_page, "fogmap_refused_uploads_total", "reason=\"forged_node\""),
            static_cast<double>(forged_uploads));
  EXPECT_EQ(metricValue(metrics_page, "fogmap_refused_uploads_total"),
            static_cast<double>(unknown_peer_uploads + forged_uploads))
      << "a refusal of another kind: the honest nodes were refused something";
  EXPECT_EQ(metricValue(metrics_page, "fogmap_geofence_denied_total"), static_cast<double>(denied_geofences));

  // The published global maps hold the honest sensors' data only, and it was applied every epoch
  // while the attacks ran.
  ASSERT_FALSE(result->epochs.empty());
  const std::uint64_t first = result->epochs.begin()->first;
  const std::uint64_t last = result->epochs.rbegin()->first;
  std::string published;  // "epoch:nodes" of every global map, for the failure messages
  for (const auto& [epoch, global] : result->epochs) {
    published += " " + std::to_string(epoch - first) + ":" + std::to_string(global.header.contributing_nodes.size());
  }
  SCOPED_TRACE("epochs after the first (" + std::to_string(first) + "): contributing nodes; attacks from " +
               std::to_string(attack_start - first) + " to " + std::to_string(attack_end - first) + "\n" + published +
               "\nsubscriber drops " + std::to_string(metricValue(metrics_page, "fogmap_subscriber_drops_total")) +
               ", late emits " + std::to_string(metricValue(metrics_page, "fogmap_late_emits_total")) +
               ", dropped epochs " + std::to_string(metricValue(metrics_page, "fogmap_dropped_epochs_total")));
  EXPECT_LE(first, attack_start);
  EXPECT_GT(last, attack_end);
  // Start-up and wind-down may miss an epoch or a node (processes start and finish one by one).
  // While the attacks ran every epoch was published with honest data, and every honest upload was
  // applied: no parent refused one, no link dropped one. (Whether every sensor made it in time for
  // an epoch's first publication is the machine's speed: an edge that the machine stalls for more
  // than a period skips that epoch by design, docs/design.md, Edge.)
  ASSERT_EQ(sender_pages.size(), t.nodes.size() - 1);
  for (const auto& [name, page] : sender_pages) {
    EXPECT_EQ(metricValue(page, "fogmap_uploads_refused_by_parent_total"), 0.0) << name << "'s uploads were refused";
    EXPECT_EQ(metricValue(page, "fogmap_dropped_uploads_total"), 0.0) << name << "'s uploads were dropped";
  }
  std::size_t complete = 0;
  for (std::uint64_t epoch = attack_start; epoch <= attack_end; ++epoch) {
    const auto published_epoch = result->epochs.find(epoch);
    ASSERT_NE(published_epoch, result->epochs.end()) << "epoch " << epoch << " was not published during the attacks";
    EXPECT_FALSE(published_epoch->second.header.contributing_nodes.empty()) << "epoch " << epoch << " during the attacks";
    EXPECT_GT(published_epoch->second.map.objects.size(), 5U) << "epoch " << epoch;
    if (published_epoch->second.header.contributing_nodes == honest) ++complete;
  }
  const std::size_t attack_epochs = attack_end - attack_start + 1;
  std::printf("%zu of %zu epochs under attack had every honest sensor\n", complete, attack_epochs);
  const std::set<std::uint32_t> honest_set(honest.begin(), honest.end());
  for (const auto& [epoch, global] : result->epochs) {
    for (const auto node : global.header.contributing_nodes) EXPECT_TRUE(honest_set.count(node)) << "epoch " << epoch;
    for (const auto& object : global.map.objects) {
      for (const auto& e : object.ellipsoids) {
        EXPECT_LT(e.id.index, kAttackIndex) << "an attacker's ellipsoid in epoch " << epoch;
        EXPECT_TRUE(honest_set.count(e.id.node)) << "epoch " << epoch;
      }
    }
  }
  if (!::testing::Test::HasFailure()) fs::remove_all(dir);
}

}  // namespace
}  // namespace fogmap
