#include "services/common/grpc_options.hpp"

#include <algorithm>
#include <climits>

namespace fogmap {
namespace {

constexpr int kKeepaliveTimeoutMs = 5000;
constexpr int kMinPingIntervalMs = 5000;  // the fastest client ping a server accepts
constexpr int kReconnectBackoffMinMs = 50;
constexpr int kReconnectBackoffMaxMs = 2000;

// gRPC takes sizes as int; anything larger means "no practical limit".
int clampToInt(std::size_t bytes) { return static_cast<int>(std::min<std::size_t>(bytes, INT_MAX)); }
int clampToInt(std::chrono::milliseconds ms) {
  return static_cast<int>(std::clamp<std::chrono::milliseconds::rep>(ms.count(), 1, INT_MAX));
}

}  // namespace

grpc::ChannelArguments channelArguments(std::size_t max_message_bytes, std::chrono::milliseconds keepalive) {
  grpc::ChannelArguments args;
  args.SetMaxSendMessageSize(clampToInt(max_message_bytes));
  args.SetMaxReceiveMessageSize(clampToInt(max_message_bytes));
  args.SetInt(GRPC_ARG_KEEPALIVE_TIME_MS, clampToInt(keepalive));
  args.SetInt(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, kKeepaliveTimeoutMs);
  args.SetInt(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 1);
  // Without this the client stops pinging after two pings with no data in between, and an idle
  // upload stream to a vanished parent would go unnoticed.
  args.SetInt(GRPC_ARG_HTTP2_MAX_PINGS_WITHOUT_DATA, 0);
  args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, kReconnectBackoffMinMs);
  args.SetInt(GRPC_ARG_MIN_RECONNECT_BACKOFF_MS, kReconnectBackoffMinMs);
  args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, kReconnectBackoffMaxMs);
  return args;
}

std::shared_ptr<grpc::Channel> makeChannel(const std::string& target, std::size_t max_message_bytes,
                                           std::chrono::milliseconds keepalive) {
  return makeChannel(target, grpc::InsecureChannelCredentials(), max_message_bytes, keepalive);
}

std::shared_ptr<grpc::Channel> makeChannel(const std::string& target,
                                           const std::shared_ptr<grpc::ChannelCredentials>& credentials,
                                           std::size_t max_message_bytes, std::chrono::milliseconds keepalive) {
  return grpc::CreateCustomChannel(target, credentials, channelArguments(max_message_bytes, keepalive));
}

std::shared_ptr<grpc::ServerCredentials> serverCredentials(const std::optional<TlsPem>& tls) {
  if (!tls) return grpc::InsecureServerCredentials();
  grpc::SslServerCredentialsOptions options(GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY);
  options.pem_root_certs = tls->ca;
  options.pem_key_cert_pairs.push_back({tls->key, tls->cert});
  return grpc::SslServerCredentials(options);
}

std::shared_ptr<grpc::ChannelCredentials> channelCredentials(const std::optional<TlsPem>& tls) {
  if (!tls) return grpc::InsecureChannelCredentials();
  grpc::SslCredentialsOptions options;
  options.pem_root_certs = tls->ca;
  options.pem_private_key = tls->key;
  options.pem_cert_chain = tls->cert;
  return grpc::SslCredentials(options);
}

std::optional<std::string> peerCertificateName(const grpc::ServerContext& context) {
  const std::shared_ptr<const grpc::AuthContext> auth = context.auth_context();
  // Only a verified peer has properties worth reading; the server requires one, this is a guard.
  if (!auth || !auth->IsPeerAuthenticated()) return std::nullopt;
  const std::vector<grpc::string_ref> names = auth->FindPropertyValues(GRPC_X509_CN_PROPERTY_NAME);
  if (names.size() != 1) return std::nullopt;
  return std::string(names.front().data(), names.front().size());
}

void configureServer(grpc::ServerBuilder& builder, std::size_t max_message_bytes) {
  builder.SetMaxReceiveMessageSize(clampToInt(max_message_bytes));
  builder.SetMaxSendMessageSize(clampToInt(max_message_bytes));
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 1);
  builder.AddChannelArgument(GRPC_ARG_HTTP2_MIN_RECV_PING_INTERVAL_WITHOUT_DATA_MS, kMinPingIntervalMs);
}

grpc::StatusCode toGrpcCode(ErrorCode code) {
  static_assert(grpc::StatusCode::INVALID_ARGUMENT == 3 && grpc::StatusCode::NOT_FOUND == 5 &&
                grpc::StatusCode::RESOURCE_EXHAUSTED == 8 && grpc::StatusCode::INTERNAL == 13 &&
                grpc::StatusCode::UNAVAILABLE == 14);
  return static_cast<grpc::StatusCode>(rpcCode(code));
}

grpc::Status toGrpcStatus(const Error& error) { return {toGrpcCode(error.code), error.message}; }

Error fromGrpcStatus(const grpc::Status& status, const std::string& call) {
  const std::string message = call + ": " + status.error_message();
  switch (status.error_code()) {
    case grpc::StatusCode::INVALID_ARGUMENT: return invalidArgument(message);
    case grpc::StatusCode::NOT_FOUND: return notFound(message);
    case grpc::StatusCode::UNAVAILABLE:
    case grpc::StatusCode::DEADLINE_EXCEEDED: return ioError(message);
    case grpc::StatusCode::RESOURCE_EXHAUSTED: return resourceExhausted(message);
    default: return Error{ErrorCode::kInternal, message};
  }
}

}  // namespace fogmap
