#pragma once
// The view's two subscriptions: the root's global maps and, where the topology has one, a tracker's
// tracks, over the same Subscribe streams as any client (mutual TLS where the credentials say so).
// Each is followed on its own thread: a message is converted (proto_convert) and handed on, a
// malformed one is refused and counted; when the stream fails, ends, or stays silent for
// `idle_timeout`, the link is reported lost with the reason and subscribed again after the
// services' reconnect backoff, until stop().
#include <chrono>
#include <cstddef>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/io/messages.hpp"
#include "common/tracking/track_snapshot.hpp"
#include "view/live_view.hpp"

namespace grpc {
class ChannelCredentials;
}  // namespace grpc

namespace fogmap::view {

enum class Stream { kRoot, kTracker };
const char* streamName(Stream stream);  // "root", "tracker"

struct FeedTarget {
  std::string target;  // host:port
  std::shared_ptr<grpc::ChannelCredentials> credentials;
};

// Called on the feed's threads (one per stream), never under a lock of the feed.
struct FeedHandlers {
  std::function<void(GlobalMapMessage)> on_map;
  std::function<void(tracking::TrackSnapshot)> on_tracks;
  std::function<void(Stream, const LinkState&)> on_link;          // connected, or lost and why
  std::function<void(Stream, const std::string& why)> on_refused;  // a message that did not convert
};

class ViewFeed {
 public:
  ViewFeed(FeedTarget root, std::optional<FeedTarget> tracker, FeedHandlers handlers, std::size_t max_message_bytes,
           std::chrono::milliseconds idle_timeout = std::chrono::seconds(3));
  ~ViewFeed();  // stop()
  ViewFeed(const ViewFeed&) = delete;
  ViewFeed& operator=(const ViewFeed&) = delete;

  // A connected stream without a message for idle_timeout is cancelled (and subscribed again).
  // Call it now and then (the view's heartbeat does, every second).
  void checkIdle();
  // Cancels the streams and joins the threads.
  void stop();

  class Follower;

 private:
  FeedHandlers handlers_;  // the followers' threads call these: declared before them
  std::vector<std::unique_ptr<Follower>> followers_;
};

}  // namespace fogmap::view
