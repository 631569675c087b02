#include "common/certs/certs.hpp"
#include "common/config/topology_presets.hpp"

#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

namespace fogmap {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

const CertTime kNow = std::chrono::system_clock::now();

PemPair makeCa(const std::string& name) {
  auto ca = makeCertificateAuthority(name, kNow - 72h, kNow + 24h);
  EXPECT_TRUE(ca.ok()) << ca.error().message;
  return ca.ok() ? *ca : PemPair{};
}

CertificateRequest request(const std::string& name, CertTime not_before = kNow - 1h, CertTime not_after = kNow + 24h) {
  return {name, {name}, {"127.0.0.1"}, not_before, not_after};
}

PemPair issue(const PemPair& ca, const CertificateRequest& r) {
  auto leaf = issueCertificate(ca, r);
  EXPECT_TRUE(leaf.ok()) << leaf.error().message;
  return leaf.ok() ? *leaf : PemPair{};
}

TEST(Certs, IssuedCertificateVerifiesAgainstItsCaAndNamesItsHolder) {
  const PemPair ca = makeCa("fogmap test CA");
  const PemPair leaf = issue(ca, request("edge-1"));
  EXPECT_NE(leaf.cert.find("BEGIN CERTIFICATE"), std::string::npos);
  EXPECT_NE(leaf.key.find("BEGIN PRIVATE KEY"), std::string::npos);
  const Status verified = verifyCertificate(leaf.cert, ca.cert, kNow);
  EXPECT_TRUE(verified.ok()) << verified.error().message;
  const auto name = certificateCommonName(leaf.cert);
  ASSERT_TRUE(name.ok()) << name.error().message;
  EXPECT_EQ(*name, "edge-1");
  // The CA verifies against itself (it is its own root).
  EXPECT_TRUE(verifyCertificate(ca.cert, ca.cert, kNow).ok());
}

TEST(Certs, CertificateDoesNotVerifyAgainstAnotherCa) {
  const PemPair ca = makeCa("fogmap test CA");
  const PemPair other = makeCa("fogmap test CA");  // the same name, another key
  const PemPair leaf = issue(ca, request("edge-1"));
  const Status verified = verifyCertificate(leaf.cert, other.cert, kNow);
  ASSERT_FALSE(verified.ok());
  EXPECT_NE(verified.error().message.find("issuer"), std::string::npos) << verified.error().message;
  // A bundle holding both CAs accepts it again.
  EXPECT_TRUE(verifyCertificate(leaf.cert, other.cert + ca.cert, kNow).ok());
}

TEST(Certs, ExpiredAndNotYetValidCertificatesFailVerification) {
  const PemPair ca = makeCa("fogmap test CA");
  const PemPair expired = issue(ca, request("edge-1", kNow - 48h, kNow - 24h));
  const Status old = verifyCertificate(expired.cert, ca.cert, kNow);
  ASSERT_FALSE(old.ok());
  EXPECT_NE(old.error().message.find("expired"), std::string::npos) << old.error().message;
  // The same certificate was valid while it lasted.
  EXPECT_TRUE(verifyCertificate(expired.cert, ca.cert, kNow - 36h).ok());
  const PemPair future = issue(ca, request("edge-1", kNow + 2h, kNow + 4h));
  const Status early = verifyCertificate(future.cert, ca.cert, kNow);
  ASSERT_FALSE(early.ok());
  EXPECT_NE(early.error().message.find("not yet valid"), std::string::npos) << early.error().message;
}

TEST(Certs, RequestsWithoutANameOrWithBadValuesAreRefused) {
  const PemPair ca = makeCa("fogmap test CA");
  EXPECT_FALSE(issueCertificate(ca, request("")).ok());
  EXPECT_FALSE(issueCertificate(ca, request("edge-1", kNow, kNow - 1s)).ok());
  CertificateRequest bad_ip = request("edge-1");
  bad_ip.ip_addresses = {"not-an-ip"};
  const auto refused = issueCertificate(ca, bad_ip);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.error().message.find("not-an-ip"), std::string::npos) << refused.error().message;
  EXPECT_FALSE(issueCertificate(PemPair{ca.cert, makeCa("other").key}, request("edge-1")).ok());
}

// Files for loadTls under a fresh directory.
class TlsFilesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("fogmap-certs-test-" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    ca_ = makeCa("fogmap test CA");
    write("ca.crt", ca_.cert);
    const PemPair sink = issue(ca_, request("sink"));
    write("sink.crt", sink.cert);
    write("sink.key", sink.key);
  }
  void TearDown() override { fs::remove_all(dir_); }
  void write(const std::string& name, const std::string& text) { std::ofstream(dir_ / name) << text; }
  TlsIdentity identity(const std::string& name) { return {dir_ / "ca.crt", dir_ / (name + ".crt"), dir_ / (name + ".key")}; }

  fs::path dir_;
  PemPair ca_;
};

TEST_F(TlsFilesTest, LoadsAValidIdentity) {
  const auto pem = loadTls(identity("sink"), kNow);
  ASSERT_TRUE(pem.ok()) << pem.error().message;
  EXPECT_EQ(pem->name, "sink");
  EXPECT_EQ(pem->ca, ca_.cert);
}

TEST_F(TlsFilesTest, AMissingFileIsNamed) {
  const auto pem = loadTls(identity("edge-9"), kNow);
  ASSERT_FALSE(pem.ok());
  EXPECT_EQ(pem.error().code, ErrorCode::kNotFound);
  EXPECT_NE(pem.error().message.find((dir_ / "edge-9.crt").string()), std::string::npos) << pem.error().message;
}

TEST_F(TlsFilesTest, GarbageAMismatchedKeyAndAnExpiredCertificateAreNamed) {
  write("junk.crt", "not a certificate");
  write("junk.key", issue(ca_, request("junk")).key);
  auto pem = loadTls(identity("junk"), kNow);
  ASSERT_FALSE(pem.ok());
  EXPECT_NE(pem.error().message.find("junk.crt"), std::string::npos) << pem.error().message;

  write("mixed.crt", issue(ca_, request("mixed")).cert);
  write("mixed.key", issue(ca_, request("mixed")).key);
  pem = loadTls(identity("mixed"), kNow);
  ASSERT_FALSE(pem.ok());
  EXPECT_NE(pem.error().message.find("is not the private key of"), std::string::npos) << pem.error().message;

  const PemPair old = issue(ca_, request("old", kNow - 48h, kNow - 24h));
  write("old.crt", old.cert);
  write("old.key", old.key);
  pem = loadTls(identity("old"), kNow);
  ASSERT_FALSE(pem.ok());
  EXPECT_NE(pem.error().message.find("old.crt"), std::string::npos) << pem.error().message;
  EXPECT_NE(pem.error().message.find("expired"), std::string::npos) << pem.error().message;
}

TEST_F(TlsFilesTest, TopologyIdentityMustCarryTheNodesName) {
  TopologyConfig t = makeStarTopology(1, "scans", 50000);
  EXPECT_FALSE(loadTls(t, "sink", kNow)->has_value()) << "TLS is off without a tls section";
  t.tls = TlsConfig{dir_ / "ca.crt", dir_, {}};
  const auto sink = loadTls(t, "sink", kNow);
  ASSERT_TRUE(sink.ok()) << sink.error().message;
  ASSERT_TRUE(sink->has_value());
  EXPECT_EQ((*sink)->name, "sink");
  // edge-1 presenting the sink's certificate is refused, naming both.
  t.nodes.back().tls = TlsFiles{dir_ / "sink.crt", dir_ / "sink.key"};
  const auto edge = loadTls(t, "edge-1", kNow);
  ASSERT_FALSE(edge.ok());
  EXPECT_NE(edge.error().message.find("issued to 'sink', not to 'edge-1'"), std::string::npos) << edge.error().message;
}

}  // namespace
}  // namespace fogmap
