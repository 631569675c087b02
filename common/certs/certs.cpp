#include "common/certs/certs.hpp"

#include <openssl/asn1.h>
#include <openssl/bio.h>
#include <openssl/bn.h>
#include <openssl/err.h>
#include <openssl/evp.h>
#include <openssl/pem.h>
#include <openssl/rand.h>
#include <openssl/x509.h>
#include <openssl/x509v3.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <memory>
#include <sstream>
#include <system_error>

namespace fogmap {
namespace {

template <class T, void (*Free)(T*)>
struct Deleter {
  void operator()(T* p) const { Free(p); }
};
using Bio = std::unique_ptr<BIO, Deleter<BIO, BIO_free_all>>;
using Key = std::unique_ptr<EVP_PKEY, Deleter<EVP_PKEY, EVP_PKEY_free>>;
using Cert = std::unique_ptr<X509, Deleter<X509, X509_free>>;
using Store = std::unique_ptr<X509_STORE, Deleter<X509_STORE, X509_STORE_free>>;
using StoreContext = std::unique_ptr<X509_STORE_CTX, Deleter<X509_STORE_CTX, X509_STORE_CTX_free>>;
using Names = std::unique_ptr<GENERAL_NAMES, Deleter<GENERAL_NAMES, GENERAL_NAMES_free>>;
using Bignum = std::unique_ptr<BIGNUM, Deleter<BIGNUM, BN_free>>;

// OpenSSL's error queue as one line (and emptied, so the next call starts clean).
std::string opensslErrors() {
  std::string out;
  while (const unsigned long code = ERR_get_error()) {
    char text[256];
    ERR_error_string_n(code, text, sizeof text);
    out += (out.empty() ? "" : "; ") + std::string(text);
  }
  return out.empty() ? "unknown OpenSSL error" : out;
}

Error failed(const std::string& what) { return Error{ErrorCode::kInternal, what + ": " + opensslErrors()}; }

Bio memoryOf(const std::string& text) {
  return Bio(BIO_new_mem_buf(text.data(), static_cast<int>(text.size())));
}

std::string textOf(BIO* bio) {
  char* data = nullptr;
  const long size = BIO_get_mem_data(bio, &data);
  return size > 0 ? std::string(data, static_cast<std::size_t>(size)) : std::string();
}

Expected<std::string> pemOf(X509* cert) {
  Bio bio(BIO_new(BIO_s_mem()));
  if (!bio || PEM_write_bio_X509(bio.get(), cert) != 1) return failed("writing a certificate");
  return textOf(bio.get());
}

Expected<std::string> pemOf(EVP_PKEY* key) {
  Bio bio(BIO_new(BIO_s_mem()));
  if (!bio || PEM_write_bio_PrivateKey(bio.get(), key, nullptr, nullptr, 0, nullptr, nullptr) != 1) {
    return failed("writing a private key");
  }
  return textOf(bio.get());
}

// Every certificate of a PEM bundle; an error when there is none.
Expected<std::vector<Cert>> readCertificates(const std::string& pem) {
  Bio bio = memoryOf(pem);
  std::vector<Cert> certs;
  while (bio) {
    Cert cert(PEM_read_bio_X509(bio.get(), nullptr, nullptr, nullptr));
    if (!cert) break;
    certs.push_back(std::move(cert));
  }
  const std::string why = opensslErrors();  // the end of the bundle leaves "no start line" behind
  if (certs.empty()) return invalidArgument("not a PEM certificate (" + why + ")");
  return certs;
}

Expected<Cert> readCertificate(const std::string& pem) {
  auto certs = readCertificates(pem);
  if (!certs) return certs.error();
  return std::move(certs->front());
}

Expected<Key> readKey(const std::string& pem) {
  Bio bio = memoryOf(pem);
  Key key(bio ? PEM_read_bio_PrivateKey(bio.get(), nullptr, nullptr, nullptr) : nullptr);
  if (!key) return invalidArgument("not a PEM private key (" + opensslErrors() + ")");
  return key;
}

Expected<Key> newEcKey() {
  Key key(EVP_EC_gen("P-256"));
  if (!key) return failed("generating an EC P-256 key");
  return key;
}

// A v3 certificate for `key` named `common_name`, with a random 127-bit serial and the validity
// given; issuer and extensions are the caller's.
Expected<Cert> newCertificate(const std::string& common_name, EVP_PKEY* key, CertTime not_before, CertTime not_after) {
  if (common_name.empty()) return invalidArgument("a certificate needs a common name");
  if (not_after <= not_before) return invalidArgument("a certificate's notAfter must be later than its notBefore");
  Cert cert(X509_new());
  if (!cert || X509_set_version(cert.get(), 2) != 1) return failed("creating a certificate");
  unsigned char serial[16];
  if (RAND_bytes(serial, sizeof serial) != 1) return failed("drawing a serial number");
  serial[0] &= 0x7F;  // positive
  serial[0] |= 0x40;  // and full length
  Bignum number(BN_bin2bn(serial, sizeof serial, nullptr));
  if (!number || BN_to_ASN1_INTEGER(number.get(), X509_get_serialNumber(cert.get())) == nullptr) {
    return failed("setting the serial number");
  }
  if (ASN1_TIME_set(X509_getm_notBefore(cert.get()), std::chrono::system_clock::to_time_t(not_before)) == nullptr ||
      ASN1_TIME_set(X509_getm_notAfter(cert.get()), std::chrono::system_clock::to_time_t(not_after)) == nullptr) {
    return failed("setting the validity");
  }
  X509_NAME* subject = X509_get_subject_name(cert.get());
  if (X509_NAME_add_entry_by_NID(subject, NID_commonName, MBSTRING_UTF8,
                                 reinterpret_cast<const unsigned char*>(common_name.c_str()), -1, -1, 0) != 1) {
    return failed("setting the common name '" + common_name + "'");
  }
  if (X509_set_pubkey(cert.get(), key) != 1) return failed("setting the public key");
  return cert;
}

// One extension in OpenSSL's configuration syntax (fixed values only: names go through
// addSubjectAltName, never through this syntax).
Status addExtension(X509* cert, X509* issuer, int nid, const char* value) {
  X509V3_CTX context;
  X509V3_set_ctx_nodb(&context);
  X509V3_set_ctx(&context, issuer, cert, nullptr, nullptr, 0);
  X509_EXTENSION* extension = X509V3_EXT_conf_nid(nullptr, &context, nid, value);
  if (extension == nullptr) return failed(std::string("building extension ") + OBJ_nid2sn(nid) + " = " + value);
  const int added = X509_add_ext(cert, extension, -1);
  X509_EXTENSION_free(extension);
  if (added != 1) return failed(std::string("adding extension ") + OBJ_nid2sn(nid));
  return {};
}

Status addSubjectAltName(X509* cert, const CertificateRequest& request) {
  if (request.dns_names.empty() && request.ip_addresses.empty()) return {};
  Names names(sk_GENERAL_NAME_new_null());
  if (!names) return failed("building subjectAltName");
  for (const auto& dns : request.dns_names) {
    GENERAL_NAME* name = GENERAL_NAME_new();
    ASN1_IA5STRING* text = ASN1_IA5STRING_new();
    if (name == nullptr || text == nullptr || ASN1_STRING_set(text, dns.data(), static_cast<int>(dns.size())) != 1) {
      GENERAL_NAME_free(name);
      ASN1_IA5STRING_free(text);
      return failed("building subjectAltName DNS:" + dns);
    }
    GENERAL_NAME_set0_value(name, GEN_DNS, text);
    sk_GENERAL_NAME_push(names.get(), name);
  }
  for (const auto& ip : request.ip_addresses) {
    ASN1_OCTET_STRING* address = a2i_IPADDRESS(ip.c_str());
    if (address == nullptr) {
      ERR_clear_error();
      return invalidArgument("subjectAltName: '" + ip + "' is not an IP address");
    }
    GENERAL_NAME* name = GENERAL_NAME_new();
    if (name == nullptr) {
      ASN1_OCTET_STRING_free(address);
      return failed("building subjectAltName IP:" + ip);
    }
    GENERAL_NAME_set0_value(name, GEN_IPADD, address);
    sk_GENERAL_NAME_push(names.get(), name);
  }
  if (X509_add1_ext_i2d(cert, NID_subject_alt_name, names.get(), 0, X509V3_ADD_DEFAULT) != 1) {
    return failed("adding subjectAltName");
  }
  return {};
}

Expected<PemPair> signedPair(X509* cert, EVP_PKEY* signer, EVP_PKEY* key) {
  if (X509_sign(cert, signer, EVP_sha256()) <= 0) return failed("signing the certificate");
  auto cert_pem = pemOf(cert);
  if (!cert_pem) return cert_pem.error();
  auto key_pem = pemOf(key);
  if (!key_pem) return key_pem.error();
  return PemPair{std::move(*cert_pem), std::move(*key_pem)};
}

// A whole file, or an error that names it.
Expected<std::string> readFile(const std::filesystem::path& path, const std::string& what) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return notFound(path.string() + ": no such file (" + what + ")");
  if (std::filesystem::is_directory(path, ec)) return ioError(path.string() + ": is a directory, not " + what);
  std::ifstream in(path, std::ios::binary);
  if (!in) return ioError(path.string() + ": cannot read " + what + " (" + std::strerror(errno) + ")");
  std::stringstream text;
  text << in.rdbuf();
  if (in.bad()) return ioError(path.string() + ": cannot read " + what);
  return text.str();
}

}  // namespace

Expected<PemPair> makeCertificateAuthority(const std::string& common_name, CertTime not_before, CertTime not_after) {
  auto key = newEcKey();
  if (!key) return key.error();
  auto cert = newCertificate(common_name, key->get(), not_before, not_after);
  if (!cert) return cert.error();
  X509* c = cert->get();
  if (X509_set_issuer_name(c, X509_get_subject_name(c)) != 1) return failed("setting the issuer");
  for (const auto& [nid, value] : {std::pair{NID_basic_constraints, "critical,CA:TRUE"},
                                   std::pair{NID_key_usage, "critical,keyCertSign,cRLSign"},
                                   std::pair{NID_subject_key_identifier, "hash"}}) {
    if (const Status s = addExtension(c, c, nid, value); !s) return s.error();
  }
  return signedPair(c, key->get(), key->get());
}

Expected<PemPair> issueCertificate(const PemPair& ca, const CertificateRequest& request) {
  auto ca_cert = readCertificate(ca.cert);
  if (!ca_cert) return invalidArgument("the CA certificate: " + ca_cert.error().message);
  auto ca_key = readKey(ca.key);
  if (!ca_key) return invalidArgument("the CA key: " + ca_key.error().message);
  if (X509_check_private_key(ca_cert->get(), ca_key->get()) != 1) {
    ERR_clear_error();
    return invalidArgument("the CA key does not belong to the CA certificate");
  }
  auto key = newEcKey();
  if (!key) return key.error();
  auto cert = newCertificate(request.common_name, key->get(), request.not_before, request.not_after);
  if (!cert) return cert.error();
  X509* c = cert->get();
  if (X509_set_issuer_name(c, X509_get_subject_name(ca_cert->get())) != 1) return failed("setting the issuer");
  for (const auto& [nid, value] : {std::pair{NID_basic_constraints, "critical,CA:FALSE"},
                                   std::pair{NID_key_usage, "critical,digitalSignature"},
                                   std::pair{NID_ext_key_usage, "serverAuth,clientAuth"},
                                   std::pair{NID_subject_key_identifier, "hash"},
                                   std::pair{NID_authority_key_identifier, "keyid:always"}}) {
    if (const Status s = addExtension(c, ca_cert->get(), nid, value); !s) return s.error();
  }
  if (const Status s = addSubjectAltName(c, request); !s) return s.error();
  return signedPair(c, ca_key->get(), key->get());
}

Status verifyCertificate(const std::string& cert, const std::string& ca_bundle, CertTime at) {
  auto leaf = readCertificate(cert);
  if (!leaf) return leaf.error();
  auto cas = readCertificates(ca_bundle);
  if (!cas) return invalidArgument("the CA bundle: " + cas.error().message);
  Store store(X509_STORE_new());
  if (!store) return failed("creating a certificate store");
  for (const Cert& ca : *cas) {
    if (X509_STORE_add_cert(store.get(), ca.get()) != 1) return failed("adding a CA certificate");
  }
  StoreContext context(X509_STORE_CTX_new());
  if (!context || X509_STORE_CTX_init(context.get(), store.get(), leaf->get(), nullptr) != 1) {
    return failed("creating a verification context");
  }
  X509_STORE_CTX_set_time(context.get(), 0, std::chrono::system_clock::to_time_t(at));
  if (X509_verify_cert(context.get()) != 1) {
    const int code = X509_STORE_CTX_get_error(context.get());
    ERR_clear_error();
    return invalidArgument(X509_verify_cert_error_string(code));
  }
  return {};
}

Expected<std::string> certificateCommonName(const std::string& cert) {
  auto parsed = readCertificate(cert);
  if (!parsed) return parsed.error();
  const X509_NAME* subject = X509_get_subject_name(parsed->get());
  const int at = X509_NAME_get_index_by_NID(subject, NID_commonName, -1);
  if (at < 0) return invalidArgument("the certificate's subject has no common name");
  if (X509_NAME_get_index_by_NID(subject, NID_commonName, at) >= 0) {
    return invalidArgument("the certificate's subject has more than one common name");
  }
  unsigned char* utf8 = nullptr;
  const int length = ASN1_STRING_to_UTF8(&utf8, X509_NAME_ENTRY_get_data(X509_NAME_get_entry(subject, at)));
  if (length < 0) return failed("reading the common name");
  std::string name(reinterpret_cast<const char*>(utf8), static_cast<std::size_t>(length));
  OPENSSL_free(utf8);
  return name;
}

Expected<TlsPem> loadTls(const TlsIdentity& files, CertTime now) {
  TlsPem pem;
  for (const auto& [path, text, what] : {std::tuple{&files.ca, &pem.ca, "the CA certificate (tls.ca)"},
                                         std::tuple{&files.cert, &pem.cert, "the certificate"},
                                         std::tuple{&files.key, &pem.key, "the certificate's private key"}}) {
    auto read = readFile(*path, what);
    if (!read) return read.error();
    *text = std::move(*read);
  }
  const auto named = [](const std::filesystem::path& path, const Error& e) {
    return invalidArgument(path.string() + ": " + e.message);
  };
  if (auto ca = readCertificates(pem.ca); !ca) return named(files.ca, ca.error());
  auto cert = readCertificate(pem.cert);
  if (!cert) return named(files.cert, cert.error());
  auto key = readKey(pem.key);
  if (!key) return named(files.key, key.error());
  if (X509_check_private_key(cert->get(), key->get()) != 1) {
    ERR_clear_error();
    return invalidArgument(files.key.string() + ": is not the private key of " + files.cert.string());
  }
  if (const Status s = verifyCertificate(pem.cert, pem.ca, now); !s) {
    return invalidArgument(files.cert.string() + ": does not verify against the CA " + files.ca.string() + ": " +
                           s.error().message);
  }
  auto name = certificateCommonName(pem.cert);
  if (!name) return named(files.cert, name.error());
  pem.name = std::move(*name);
  return pem;
}

Expected<std::optional<TlsPem>> loadTls(const TopologyConfig& topology, const std::string& name, CertTime now) {
  const std::optional<TlsIdentity> files = topology.tlsIdentity(name);
  if (!files) return std::optional<TlsPem>{};
  auto pem = loadTls(*files, now);
  if (!pem) return pem.error();
  if (pem->name != name) {
    return invalidArgument(files->cert.string() + ": the certificate is issued to '" + pem->name + "', not to '" + name +
                           "' (peers know an endpoint by its certificate's common name)");
  }
  return std::optional<TlsPem>(std::move(*pem));
}

}  // namespace fogmap
