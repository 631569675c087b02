#pragma once
// Channel and server settings shared by every service: message size limits, keepalive, reconnect
// backoff, and the one error -> status mapping.
#include <chrono>
#include <cstddef>
#include <memory>
#include <string>

#include <grpcpp/grpcpp.h>

#include "common/status.hpp"

namespace fogmap {

// Client pings every `keepalive` (>= 5 s: servers built by configureServer refuse faster pings)
// and drops the connection when a ping is not answered in 5 s; pings also run on idle
// connections so a dead parent is noticed before the next upload. Reconnect backoff 50 ms..2 s.
grpc::ChannelArguments channelArguments(std::size_t max_message_bytes,
                                        std::chrono::milliseconds keepalive = std::chrono::seconds(10));
// An insecure channel (deployments run on a private network) with channelArguments.
std::shared_ptr<grpc::Channel> makeChannel(const std::string& target, std::size_t max_message_bytes,
                                           std::chrono::milliseconds keepalive = std::chrono::seconds(10));
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
