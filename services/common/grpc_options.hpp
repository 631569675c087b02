#pragma once
// Channel and server settings shared by every service: message size limits, keepalive, reconnect
// backoff, transport credentials (plaintext or mutual TLS) and the peer's identity, and the one
// error -> status mapping.
#include <chrono>
#include <cstddef>
#include <memory>
#include <optional>
#include <string>

#include <grpcpp/grpcpp.h>

#include "common/certs/certs.hpp"
#include "common/base/status.hpp"
#include "services/common/endpoint.hpp"  // every target and listening address is written by it

namespace fogmap {

// Client pings every `keepalive` (>= 5 s: servers built by configureServer refuse faster pings)
// and drops the connection when a ping is not answered in 5 s; pings also run on idle
// connections so a dead parent is noticed before the next upload. Reconnect backoff 50 ms..2 s.
grpc::ChannelArguments channelArguments(std::size_t max_message_bytes,
                                        std::chrono::milliseconds keepalive = std::chrono::seconds(10));
// A plaintext channel with channelArguments (topologies without a tls section).
std::shared_ptr<grpc::Channel> makeChannel(const std::string& target, std::size_t max_message_bytes,
                                           std::chrono::milliseconds keepalive = std::chrono::seconds(10));
// A channel with the given credentials (channelCredentials) and channelArguments.
std::shared_ptr<grpc::Channel> makeChannel(const std::string& target,
                                           const std::shared_ptr<grpc::ChannelCredentials>& credentials,
                                           std::size_t max_message_bytes,
                                           std::chrono::milliseconds keepalive = std::chrono::seconds(10));

// Transport credentials, built here only. Without TLS (std::nullopt): plaintext. With TLS: the
// server presents its certificate and requires and verifies every client's against the CA
// (GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY); a client presents its certificate
// and verifies the server's against the CA and the target's host (an IP subjectAltName for
// "127.0.0.1:port").
std::shared_ptr<grpc::ServerCredentials> serverCredentials(const std::optional<TlsPem>& tls);
std::shared_ptr<grpc::ChannelCredentials> channelCredentials(const std::optional<TlsPem>& tls);
// The common name of the peer's verified certificate (auth context property x509_common_name);
// std::nullopt on a plaintext call, or when the certificate has no single common name.
std::optional<std::string> peerCertificateName(const grpc::ServerContext& context);
// Message size limits, and keepalive enforcement that accepts client pings every 5 s or slower,
// also on connections without calls.
void configureServer(grpc::ServerBuilder& builder, std::size_t max_message_bytes);
// The error -> status mapping, in one place: kInvalidArgument -> INVALID_ARGUMENT, kNotFound ->
// NOT_FOUND, kIo -> UNAVAILABLE, kInternal -> INTERNAL, kResourceExhausted -> RESOURCE_EXHAUSTED.
grpc::StatusCode toGrpcCode(ErrorCode code);
// toGrpcCode with the message kept.
grpc::Status toGrpcStatus(const Error& error);
// The way back, for clients: INVALID_ARGUMENT -> kInvalidArgument, NOT_FOUND -> kNotFound,
// UNAVAILABLE and DEADLINE_EXCEEDED -> kIo, RESOURCE_EXHAUSTED -> kResourceExhausted, anything
// else -> kInternal; "<call>: <message>".
Error fromGrpcStatus(const grpc::Status& status, const std::string& call);

}  // namespace fogmap
