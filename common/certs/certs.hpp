#pragma once
// Certificates for mutual TLS (docs/design.md "Security"), with the OpenSSL C API: a CA, leaf
// certificates for nodes and clients, and the check every endpoint runs on its own files when it
// starts. Everything is PEM text; nothing here knows gRPC.
#include <chrono>
#include <optional>
#include <string>
#include <vector>

#include "common/base/status.hpp"
#include "common/config/topology.hpp"

namespace fogmap {

using CertTime = std::chrono::system_clock::time_point;

// A certificate and its private key (PKCS#8, unencrypted), PEM.
struct PemPair {
  std::string cert;
  std::string key;
};

struct CertificateRequest {
  std::string common_name;                // the holder's identity: a node's or a client's name
  std::vector<std::string> dns_names;     // subjectAltName DNS entries
  std::vector<std::string> ip_addresses;  // subjectAltName IP entries (IPv4), so "ip:port" targets verify
  CertTime not_before;
  CertTime not_after;
};

// A self-signed CA: new EC P-256 key, CN = common_name, CA:TRUE, keyCertSign and cRLSign, valid
// from not_before to not_after.
Expected<PemPair> makeCertificateAuthority(const std::string& common_name, CertTime not_before, CertTime not_after);
// A leaf certificate signed by `ca`: new EC P-256 key, CN and subjectAltName from the request,
// CA:FALSE, digitalSignature, extended key usage serverAuth and clientAuth.
Expected<PemPair> issueCertificate(const PemPair& ca, const CertificateRequest& request);

// Succeeds when `cert` chains to a certificate of `ca_bundle` and every certificate of the chain
// is valid at `at`; the error says why not (OpenSSL's reason).
Status verifyCertificate(const std::string& cert, const std::string& ca_bundle, CertTime at);
// The subject's common name of a PEM certificate (an error when it has none, or several).
Expected<std::string> certificateCommonName(const std::string& cert);

// One endpoint's TLS material, read and checked.
struct TlsPem {
  std::string ca;    // the CA bundle peers must chain to
  std::string cert;  // this endpoint's certificate
  std::string key;   // and its private key
  std::string name;  // the certificate's common name: this endpoint's identity
};

// Reads the files of `files` and checks them: each exists and is readable (kNotFound, kIo), each is
// PEM of the right kind, the key belongs to the certificate, and the certificate chains to the CA
// and is valid at `now` (kInvalidArgument). Every error names its file.
Expected<TlsPem> loadTls(const TlsIdentity& files, CertTime now);
// The TLS material of node or client `name` of the topology: std::nullopt when TLS is off, else its
// files (TopologyConfig::tlsIdentity) loaded as above, and the certificate must be issued to `name`.
Expected<std::optional<TlsPem>> loadTls(const TopologyConfig& topology, const std::string& name, CertTime now);

}  // namespace fogmap
