#pragma once
// `fogctl view` assembled: the feed's messages become the live view's events in the hub, the web
// server hands them to the pages, and a heartbeat (every second) publishes the links' state and
// cancels a stream that went silent. Owns every part and stops them in order: heartbeat, feed,
// then the server (whose pages' streams end).
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include <prometheus/counter.h>
#include <prometheus/gauge.h>
#include <prometheus/registry.h>

#include "common/base/burst_log.hpp"
#include "common/base/clock.hpp"
#include "common/base/status.hpp"
#include "services/common/periodic.hpp"
#include "view/event_hub.hpp"
#include "view/live_view.hpp"
#include "view/view_feed.hpp"
#include "view/web_server.hpp"

namespace fogmap::view {

struct ViewOptions {
  WebServerOptions web;                 // metrics_text is the runtime's own
  std::size_t max_pages = 16;           // pages reading events at once; one more is answered 503
  std::size_t max_message_bytes = 64U << 20;
  std::chrono::milliseconds heartbeat{1000};
  std::chrono::milliseconds idle_timeout{3000};  // a stream silent this long is subscribed again
  NowNs now = systemNowNs;  // the status events' server time, the log's bursts
};

class ViewRuntime {
 public:
  static Expected<std::unique_ptr<ViewRuntime>> start(ViewConfig config, FeedTarget root, std::optional<FeedTarget> tracker,
                                                       ViewOptions options);
  ~ViewRuntime();
  ViewRuntime(const ViewRuntime&) = delete;
  ViewRuntime& operator=(const ViewRuntime&) = delete;

  std::string url() const { return server_->url(); }
  std::uint16_t port() const { return server_->port(); }
  const EventHub& hub() const { return hub_; }

 private:
  ViewRuntime(ViewConfig config, FeedTarget root, std::optional<FeedTarget> tracker, ViewOptions options);
  void onMap(const GlobalMapMessage& global);
  void onTracks(const tracking::TrackSnapshot& snapshot);
  void onLink(Stream stream, const LinkState& link);
  void onRefused(Stream stream, const std::string& why);
  void publishStatus();  // under mutex_
  std::string metricsText();

  ViewOptions options_;
  std::mutex mutex_;  // live_ and the links
  LiveView live_;
  LinkState root_;
  std::optional<LinkState> tracker_;
  EventHub hub_;

  std::shared_ptr<prometheus::Registry> registry_;
  prometheus::Family<prometheus::Counter>& messages_;
  prometheus::Family<prometheus::Counter>& refused_;
  prometheus::Family<prometheus::Counter>& losses_;
  prometheus::Gauge& pages_;
  prometheus::Counter& pages_refused_;
  prometheus::Counter& events_published_;
  prometheus::Counter& events_skipped_;
  std::uint64_t counted_refused_pages_ = 0;  // the hub's totals already added to the counters
  std::uint64_t counted_published_ = 0;
  std::uint64_t counted_skipped_ = 0;
  std::mutex metrics_mutex_;
  BurstLog log_;  // malformed messages: one line per burst

  FeedTarget root_target_;
  std::optional<FeedTarget> tracker_target_;
  std::unique_ptr<WebServer> server_;
  std::unique_ptr<ViewFeed> feed_;
  std::unique_ptr<Periodic> heartbeat_;
};

}  // namespace fogmap::view
