#pragma once
// The tracker's LiDAR input: a subscription to the root's GlobalMapService (on-time maps only),
// re-opened with capped backoff whenever the root goes away, each global map handed on in domain
// types. Malformed maps are counted and skipped.
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include <grpcpp/grpcpp.h>

#include "common/io/messages.hpp"

namespace fogmap {

struct GlobalMapFeedHooks {
  std::function<void(const GlobalMapMessage&, std::size_t bytes)> on_map;
  std::function<void(const std::string& why)> on_malformed;
  std::function<void()> on_reconnect;  // a subscription re-opened after the first
};

class GlobalMapFeed {
 public:
  GlobalMapFeed(std::shared_ptr<grpc::Channel> channel, GlobalMapFeedHooks hooks,
                std::chrono::milliseconds backoff_initial = std::chrono::milliseconds(50),
                std::chrono::milliseconds backoff_max = std::chrono::milliseconds(2000));
  ~GlobalMapFeed();
  GlobalMapFeed(const GlobalMapFeed&) = delete;
  GlobalMapFeed& operator=(const GlobalMapFeed&) = delete;

  // Ends the subscription and joins the thread (within a moment: the call is cancelled).
  void stop();
  bool connected() const { return connected_.load(); }

 private:
  void run();

  std::shared_ptr<grpc::Channel> channel_;
  GlobalMapFeedHooks hooks_;
  std::chrono::milliseconds backoff_initial_;
  std::chrono::milliseconds backoff_max_;
  std::mutex mutex_;
  std::condition_variable wake_;
  grpc::ClientContext* context_ = nullptr;  // the open call, cancelled by stop()
  bool stopping_ = false;
  std::atomic<bool> connected_{false};
  std::thread thread_;
};

}  // namespace fogmap
