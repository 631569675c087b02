// The aggregator's gRPC adapters with mutual TLS, over real sockets on loopback: the peer's
// certificate is its identity. A stream's child is fixed by the certificate, a certificate that
// names no child gets every upload refused, only geofence clients may set geofences, and clients
// without a valid certificate never get past the handshake.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "common/certs/certs.hpp"
#include "common/geometry/geofence.hpp"
#include "services/common/grpc_options.hpp"
#include "services/common/metrics.hpp"
#include "services/common/proto_convert.hpp"
#include "services/merge_aggregator/aggregator_runtime.hpp"
#include "services/merge_aggregator/global_map_service.hpp"
#include "services/merge_aggregator/ingest_service.hpp"
#include "tests/support/epoch_times.hpp"
#include "tests/support/test_server.hpp"

namespace fogmap {
namespace {

using namespace std::chrono_literals;

using test_support::kE0;
using test_support::kMaxMessageBytes;
using test_support::kMs;
using test_support::kT0;

const CertTime kCertNow = std::chrono::system_clock::now();  // the certificates' validity is around it

// A certificate authority of the test and the identities it issues.
class TestPki {
 public:
  TestPki() {
    auto ca = makeCertificateAuthority("fogmap test CA", kCertNow - 72h, kCertNow + 24h);
    EXPECT_TRUE(ca.ok()) << ca.error().message;
    if (ca.ok()) ca_ = *ca;
  }
  // `name`'s identity, valid now unless told otherwise, trusting this CA.
  TlsPem identity(const std::string& name, CertTime not_before = kCertNow - 1h, CertTime not_after = kCertNow + 1h) const {
    auto leaf = issueCertificate(ca_, {name, {name}, {"127.0.0.1"}, not_before, not_after});
    EXPECT_TRUE(leaf.ok()) << leaf.error().message;
    return leaf.ok() ? TlsPem{ca_.cert, leaf->cert, leaf->key, name} : TlsPem{};
  }
  const std::string& caCert() const { return ca_.cert; }

 private:
  PemPair ca_;
};

// A root aggregator over children edge-1 (id 1) and edge-2 (id 2), served with mutual TLS on
// 127.0.0.1; its clock stands still at epoch 1.
class TlsRoot {
 public:
  TlsRoot(const TlsPem& tls, std::vector<std::string> geofence_clients, Metrics* metrics)
      : aggregator_(makeCore()),
        ingest_(aggregator_, metrics, Relay{}, [] { return kT0 + 105 * kMs; }),
        global_maps_(aggregator_, metrics, 16, 20ms) {
    ingest_.identifyPeersByCertificate();
    global_maps_.allowGeofenceSetters(std::move(geofence_clients));
    grpc::ServerBuilder builder;
    configureServer(builder, kMaxMessageBytes);
    builder.AddListeningPort("127.0.0.1:0", serverCredentials(tls), &port_);
    builder.RegisterService(&ingest_);
    builder.RegisterService(&global_maps_);
    server_ = builder.BuildAndStart();
  }
  ~TlsRoot() {
    ingest_.stopAccepting();
    global_maps_.shutdown(0ms);
    if (server_) server_->Shutdown(std::chrono::system_clock::now() + 2s);
  }

  bool started() const { return server_ != nullptr && port_ != 0; }
  // A channel presenting `client` (plaintext when std::nullopt).
  std::shared_ptr<grpc::Channel> channelAs(const std::optional<TlsPem>& client) const {
    return makeChannel("127.0.0.1:" + std::to_string(port_), channelCredentials(client), kMaxMessageBytes);
  }
  std::shared_ptr<grpc::Channel> channelWith(const std::shared_ptr<grpc::ChannelCredentials>& credentials) const {
    return makeChannel("127.0.0.1:" + std::to_string(port_), credentials, kMaxMessageBytes);
  }
  AggregatorCounters counters() {
    return aggregator_.with([](MergeAggregator& core) { return core.counters(); });
  }
  std::size_t liveChildren() {
    return aggregator_.with([](MergeAggregator& core) { return core.liveChildren(kT0 + 105 * kMs); });
  }
  const GlobalMapService& globalMaps() const { return global_maps_; }

 private:
  static MergeAggregator makeCore() {
    AggregatorConfig config;
    config.node = 100;
    config.is_root = true;
    config.children = {{1, {1}, "edge-1"}, {2, {2}, "edge-2"}};
    auto core = MergeAggregator::create(std::move(config));
    EXPECT_TRUE(core.ok());
    return std::move(core).value();
  }

  SharedAggregator aggregator_;
  IngestService ingest_;
  GlobalMapService global_maps_;
  int port_ = 0;
  std::unique_ptr<grpc::Server> server_;
};

// One upload stream on `channel`, written and answered in lock step.
class Uploader {
 public:
  explicit Uploader(const std::shared_ptr<grpc::Channel>& channel) : stub_(v1::MapIngest::NewStub(channel)) {
    context_.set_deadline(std::chrono::system_clock::now() + 10s);
    stream_ = stub_->Push(&context_);
  }
  // The answer to a map of `node` for epoch 1 (std::nullopt: the stream failed).
  std::optional<v1::Ack> sendMap(std::uint64_t sequence, std::uint32_t node) {
    std::mt19937_64 rng(sequence);
    std::uniform_real_distribution<double> pos(-5.0, 5.0);
    Ellipsoid e;
    e.id = {node, kE0 + 1, static_cast<std::uint32_t>(sequence)};
    e.center = {pos(rng), pos(rng), 1.0};
    e.shape = Eigen::Matrix3d::Identity() * 0.25;
    e.point_count = 10;
    MapMessage message;
    message.header.node = node;
    message.header.epoch = kE0 + 1;
    message.header.sensor_time_ns = kT0 + 100 * kMs;
    message.header.contributing_nodes = {node};
    message.map = localMap({e});
    v1::Upload upload;
    *upload.mutable_map() = toProto(message);
    return send(sequence, std::move(upload));
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
  auto stub = v1::GlobalMapService::NewStub(channel);
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + 10s);
  return stub->SetGeofence(&context, toProto(boxGeofence(name, {0, -4, -3}, {20, 4, 3})), reply);
}

grpc::Status queryGeofences(const std::shared_ptr<grpc::Channel>& channel) {
  auto stub = v1::GlobalMapService::NewStub(channel);
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + 10s);
  v1::GeofenceReport report;
  return stub->QueryGeofences(&context, v1::GeofenceQuery{}, &report);
}

std::string describe(const std::optional<v1::Ack>& ack) {
  return ack ? v1::AckStatus_Name(ack->status()) + " (" + ack->reason() + ")" : std::string("no answer");
}

TEST(TlsService, ChildCertificateFixesTheStreamBeforeItsFirstUpload) {
  const TestPki pki;
  TlsRoot root(pki.identity("sink"), {}, nullptr);
  ASSERT_TRUE(root.started());
  Uploader edge1(root.channelAs(pki.identity("edge-1")));
  // Without TLS a first upload of node 2 would make this edge 2's stream; the certificate says edge 1.
  const auto forged = edge1.sendMap(1, 2);
  ASSERT_TRUE(forged.has_value());
  EXPECT_EQ(forged->status(), v1::ACK_STATUS_REFUSED) << describe(forged);
  const auto own = edge1.sendMap(2, 1);
  ASSERT_TRUE(own.has_value());
  EXPECT_EQ(own->status(), v1::ACK_STATUS_APPLIED) << describe(own);
  EXPECT_TRUE(edge1.finish().ok());
  const AggregatorCounters counters = root.counters();
  EXPECT_EQ(counters.refused.at(Refusal::kForgedNode), 1U);
  EXPECT_EQ(counters.refusedTotal(), 1U);
  EXPECT_EQ(counters.accepted, 1U);
}

TEST(TlsService, NonChildCertificateGetsEveryUploadRefusedAsUnknownPeer) {
  const TestPki pki;
  Metrics metrics("", "merge-aggregator", "sink");
  TlsRoot root(pki.identity("sink"), {"operator"}, &metrics);
  ASSERT_TRUE(root.started());
  // A certificate from the right CA, of a name that is no child (even a geofence client's).
  for (const std::string name : {"intruder", "operator"}) {
    SCOPED_TRACE(name);
    Uploader intruder(root.channelAs(pki.identity(name)));
    for (std::uint64_t sequence = 1; sequence <= 3; ++sequence) {
      const auto ack = intruder.sendMap(sequence, static_cast<std::uint32_t>(sequence % 2 + 1));  // claims edge 1 or 2
      ASSERT_TRUE(ack.has_value()) << "the stream stays open and answers";
      EXPECT_EQ(ack->sequence(), sequence);
      EXPECT_EQ(ack->status(), v1::ACK_STATUS_REFUSED) << describe(ack);
      EXPECT_EQ(ack->reason().rfind("unknown_peer: ", 0), 0U) << describe(ack);
      EXPECT_NE(ack->reason().find("'" + name + "'"), std::string::npos) << describe(ack);
    }
    const auto headerless = intruder.send(4, v1::Upload{});
    ASSERT_TRUE(headerless.has_value());
    EXPECT_EQ(headerless->status(), v1::ACK_STATUS_REFUSED) << describe(headerless);
    EXPECT_TRUE(intruder.finish().ok());
  }
  const AggregatorCounters counters = root.counters();
  EXPECT_EQ(counters.refused.at(Refusal::kUnknownPeer), 8U);
  EXPECT_EQ(counters.refusedTotal(), 8U);
  EXPECT_EQ(counters.accepted, 0U);
  EXPECT_EQ(root.liveChildren(), 0U) << "an unknown peer makes no child live";
}

TEST(TlsService, OnlyGeofenceClientsMaySetGeofencesAndAnyPeerMayQuery) {
  const TestPki pki;
  Metrics metrics("", "merge-aggregator", "sink");
  TlsRoot root(pki.identity("sink"), {"operator"}, &metrics);
  ASSERT_TRUE(root.started());
  v1::SetGeofenceReply reply;
  for (const std::string name : {"edge-1", "intruder"}) {
    const grpc::Status denied = setGeofence(root.channelAs(pki.identity(name)), "forbidden", &reply);
    EXPECT_EQ(denied.error_code(), grpc::StatusCode::PERMISSION_DENIED) << name << ": " << denied.error_message();
    EXPECT_NE(denied.error_message().find("'" + name + "'"), std::string::npos) << denied.error_message();
    const grpc::Status query = queryGeofences(root.channelAs(pki.identity(name)));
    EXPECT_TRUE(query.ok()) << name << ": " << query.error_message();
  }
  EXPECT_EQ(root.globalMaps().deniedGeofences(), 2U);
  double exported = 0.0;
  for (const auto& family : metrics.registry().Collect()) {
    if (family.name == "fogmap_geofence_denied_total") exported += family.metric.at(0).counter.value;
  }
  EXPECT_EQ(exported, 2.0);
  const grpc::Status allowed = setGeofence(root.channelAs(pki.identity("operator")), "front", &reply);
  ASSERT_TRUE(allowed.ok()) << allowed.error_message();
  EXPECT_EQ(reply.geofence_count(), 1U) << "the denied geofences were never set";
}

TEST(TlsService, ClientsWithoutAValidCertificateNeverGetPastTheHandshake) {
  const TestPki pki;
  const TestPki other;  // another CA: its certificates mean nothing here
  TlsRoot root(pki.identity("sink"), {"operator"}, nullptr);
  ASSERT_TRUE(root.started());
  grpc::SslCredentialsOptions no_certificate;
  no_certificate.pem_root_certs = pki.caCert();
  TlsPem wrong_ca = other.identity("edge-1");
  wrong_ca.ca = pki.caCert();  // it trusts the server; the server does not trust it
  const std::vector<std::pair<std::string, std::shared_ptr<grpc::ChannelCredentials>>> clients = {
      {"plaintext", grpc::InsecureChannelCredentials()},
      {"TLS without a client certificate", grpc::SslCredentials(no_certificate)},
      {"a certificate from another CA", channelCredentials(wrong_ca)},
      {"an expired certificate", channelCredentials(pki.identity("edge-1", kCertNow - 48h, kCertNow - 24h))},
  };
  for (const auto& [what, credentials] : clients) {
    SCOPED_TRACE(what);
    const auto channel = root.channelWith(credentials);
    EXPECT_EQ(queryGeofences(channel).error_code(), grpc::StatusCode::UNAVAILABLE);
    v1::SetGeofenceReply reply;
    EXPECT_EQ(setGeofence(channel, "forbidden", &reply).error_code(), grpc::StatusCode::UNAVAILABLE);
    Uploader uploader(channel);
    EXPECT_FALSE(uploader.sendMap(1, 1).has_value()) << "an upload was answered";
    EXPECT_FALSE(uploader.finish().ok());
  }
  // Handshake failures happen inside gRPC, before any handler: nothing reached the core.
  EXPECT_EQ(root.counters().refusedTotal(), 0U);
  EXPECT_EQ(root.counters().accepted, 0U);
  EXPECT_EQ(root.liveChildren(), 0U);
  EXPECT_EQ(root.globalMaps().deniedGeofences(), 0U);
  // The same calls with a valid certificate go through.
  EXPECT_TRUE(queryGeofences(root.channelAs(pki.identity("edge-1"))).ok());
  Uploader edge1(root.channelAs(pki.identity("edge-1")));
  const auto applied = edge1.sendMap(1, 1);
  ASSERT_TRUE(applied.has_value());
  EXPECT_EQ(applied->status(), v1::ACK_STATUS_APPLIED) << describe(applied);
}

}  // namespace
}  // namespace fogmap
