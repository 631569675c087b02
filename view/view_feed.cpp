#include "view/view_feed.hpp"

#include <atomic>
#include <condition_variable>
#include <mutex>
#include <thread>
#include <utility>

#include <grpcpp/grpcpp.h>

#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/backoff.hpp"
#include "services/common/grpc_options.hpp"
#include "services/common/proto_convert.hpp"

namespace fogmap::view {

const char* streamName(Stream stream) { return stream == Stream::kRoot ? "root" : "tracker"; }

class ViewFeed::Follower {
 public:
  Follower(Stream stream, FeedTarget target, const FeedHandlers& handlers, std::size_t max_message_bytes,
           std::chrono::milliseconds idle_timeout)
      : stream_(stream),
        target_(std::move(target)),
        handlers_(handlers),
        max_message_bytes_(max_message_bytes),
        idle_timeout_(idle_timeout),
        thread_([this] { run(); }) {}
  ~Follower() { stop(); }

  void checkIdle() {
    std::lock_guard lock(mutex_);
    if (context_ != nullptr && receiving_ && std::chrono::steady_clock::now() - last_message_ > idle_timeout_) {
      idle_ = true;
      context_->TryCancel();
    }
  }

  void stop() {
    {
      std::lock_guard lock(mutex_);
      stopping_ = true;
      if (context_ != nullptr) context_->TryCancel();
    }
    wake_.notify_all();
    if (thread_.joinable()) thread_.join();
  }

 private:
  void report(bool connected, std::string detail) {
    if (handlers_.on_link) handlers_.on_link(stream_, LinkState{connected, target_.target, std::move(detail)});
  }

  // One subscription: reads until the stream ends; the reason it ended, or empty when stopping.
  template <class Stub, class Request, class Message, class Convert>
  std::string follow(Stub& stub, const Request& request, Convert&& deliver) {
    grpc::ClientContext context;
    {
      std::lock_guard lock(mutex_);
      if (stopping_) return {};
      context_ = &context;
      receiving_ = false;
      idle_ = false;
    }
    auto reader = stub.Subscribe(&context, request);
    Message message;
    while (reader->Read(&message)) {
      bool first = false;
      {
        std::lock_guard lock(mutex_);
        first = !receiving_;
        receiving_ = true;
        last_message_ = std::chrono::steady_clock::now();
      }
      if (first) {
        backoff_.reset();
        report(true, "");
      }
      deliver(message);
    }
    const grpc::Status status = reader->Finish();
    std::lock_guard lock(mutex_);
    context_ = nullptr;
    if (stopping_) return {};
    if (idle_) return "no message for " + std::to_string(idle_timeout_.count()) + " ms";
    if (status.ok()) return "the server ended the stream";
    return status.error_message().empty() ? "the stream failed (code " + std::to_string(status.error_code()) + ")"
                                          : status.error_message();
  }

  void run() {
    report(false, "connecting");
    const auto channel = makeChannel(target_.target, target_.credentials, max_message_bytes_);
    const auto refuse = [this](const Error& error) {
      if (handlers_.on_refused) handlers_.on_refused(stream_, error.message);
    };
    while (true) {
      std::string why;
      if (stream_ == Stream::kRoot) {
        auto stub = v1::GlobalMapService::NewStub(channel);
        why = follow<v1::GlobalMapService::Stub, v1::SubscribeRequest, v1::GlobalMap>(
            *stub, v1::SubscribeRequest{}, [&](const v1::GlobalMap& m) {
              auto global = fromProto(m);
              if (!global) return refuse(global.error());
              if (handlers_.on_map) handlers_.on_map(std::move(*global));
            });
      } else {
        auto stub = v1::TrackerService::NewStub(channel);
        why = follow<v1::TrackerService::Stub, v1::TrackSubscribeRequest, v1::TrackList>(
            *stub, v1::TrackSubscribeRequest{}, [&](const v1::TrackList& m) {
              auto tracks = fromProto(m);
              if (!tracks) return refuse(tracks.error());
              if (handlers_.on_tracks) handlers_.on_tracks(std::move(*tracks));
            });
      }
      std::unique_lock lock(mutex_);
      if (stopping_) return;
      const auto wait = backoff_.next();
      lock.unlock();
      report(false, why + "; retrying in " + std::to_string(wait.count()) + " ms");
      lock.lock();
      if (wake_.wait_for(lock, wait, [this] { return stopping_; })) return;
    }
  }

  const Stream stream_;
  const FeedTarget target_;
  const FeedHandlers& handlers_;
  const std::size_t max_message_bytes_;
  const std::chrono::milliseconds idle_timeout_;
  Backoff backoff_{std::chrono::milliseconds(200), std::chrono::seconds(2)};
  std::mutex mutex_;
  std::condition_variable wake_;
  grpc::ClientContext* context_ = nullptr;  // the subscription in progress
  bool receiving_ = false;
  bool idle_ = false;
  bool stopping_ = false;
  std::chrono::steady_clock::time_point last_message_{};
  std::thread thread_;  // last: it starts once every member above is ready
};

ViewFeed::ViewFeed(FeedTarget root, std::optional<FeedTarget> tracker, FeedHandlers handlers, std::size_t max_message_bytes,
                   std::chrono::milliseconds idle_timeout)
    : handlers_(std::move(handlers)) {
  followers_.push_back(std::make_unique<Follower>(Stream::kRoot, std::move(root), handlers_, max_message_bytes, idle_timeout));
  if (tracker) {
    followers_.push_back(std::make_unique<Follower>(Stream::kTracker, std::move(*tracker), handlers_, max_message_bytes, idle_timeout));
  }
}

ViewFeed::~ViewFeed() { stop(); }

void ViewFeed::checkIdle() {
  for (auto& f : followers_) f->checkIdle();
}

void ViewFeed::stop() {
  for (auto& f : followers_) f->stop();
}

}  // namespace fogmap::view
