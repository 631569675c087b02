#pragma once
// A real gRPC server on 127.0.0.1 serving one in-process service: what a test stands in for a
// parent, a tracker or a root with; and the message size it and the tests' channels allow.
#include <chrono>
#include <cstddef>
#include <memory>
#include <string>

#include <grpcpp/grpcpp.h>

#include "services/common/grpc_options.hpp"

namespace fogmap::test_support {

inline constexpr std::size_t kMaxMessageBytes = 64U << 20;

// Serves `service` until stopped or destroyed; port 0 picks a free port.
class TestServer {
 public:
  explicit TestServer(grpc::Service& service, int port = 0) {
    grpc::ServerBuilder builder;
    configureServer(builder, kMaxMessageBytes);
    builder.AddListeningPort("127.0.0.1:" + std::to_string(port), grpc::InsecureServerCredentials(), &port_);
    builder.RegisterService(&service);
    server_ = builder.BuildAndStart();
  }
  ~TestServer() { stop(); }
  TestServer(const TestServer&) = delete;
  TestServer& operator=(const TestServer&) = delete;

  bool started() const { return server_ != nullptr && port_ > 0; }
  int port() const { return port_; }
  std::string target() const { return "127.0.0.1:" + std::to_string(port_); }

  // Cancels open streams at once: a streaming handler would otherwise keep Shutdown waiting forever.
  void stop() {
    if (!server_) return;
    server_->Shutdown(std::chrono::system_clock::now());
    server_->Wait();
    server_.reset();
  }

 private:
  int port_ = 0;
  std::unique_ptr<grpc::Server> server_;
};

}  // namespace fogmap::test_support
