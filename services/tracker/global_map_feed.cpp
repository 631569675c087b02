#include "services/tracker/global_map_feed.hpp"

#include <algorithm>
#include <utility>

#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/backoff.hpp"
#include "services/common/proto_convert.hpp"

namespace fogmap {

GlobalMapFeed::GlobalMapFeed(std::shared_ptr<grpc::Channel> channel, GlobalMapFeedHooks hooks,
                             std::chrono::milliseconds backoff_initial, std::chrono::milliseconds backoff_max)
    : channel_(std::move(channel)),
      hooks_(std::move(hooks)),
      backoff_initial_(backoff_initial),
      backoff_max_(backoff_max),
      thread_([this] { run(); }) {}

GlobalMapFeed::~GlobalMapFeed() { stop(); }

void GlobalMapFeed::stop() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
    if (context_ != nullptr) context_->TryCancel();
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void GlobalMapFeed::run() {
  auto stub = v1::GlobalMapService::NewStub(channel_);
  Backoff backoff(backoff_initial_, backoff_max_);
  bool first = true;
  while (true) {
    grpc::ClientContext context;
    {
      std::lock_guard lock(mutex_);
      if (stopping_) return;
      context_ = &context;
    }
    if (!first && hooks_.on_reconnect) hooks_.on_reconnect();
    first = false;
    // Every epoch's first publication, late ones included (the root publishes epochs in order, so
    // they come in order); the node skips revisions (their epoch was offered already).
    v1::SubscribeRequest request;
    auto reader = stub->Subscribe(&context, request);
    v1::GlobalMap message;
    while (reader->Read(&message)) {
      connected_ = true;
      backoff.reset();  // the root answers: the next failure starts from the first step
      auto global = fromProto(message);
      if (!global) {
        if (hooks_.on_malformed) hooks_.on_malformed(global.error().message);
        continue;
      }
      if (hooks_.on_map) hooks_.on_map(*global, message.ByteSizeLong());
    }
    connected_ = false;
    (void)reader->Finish();
    std::unique_lock lock(mutex_);
    context_ = nullptr;
    if (wake_.wait_for(lock, backoff.next(), [&] { return stopping_; })) return;
  }
}

}  // namespace fogmap
