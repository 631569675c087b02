#include "view/view_runtime.hpp"

#include <prometheus/family.h>
#include <prometheus/text_serializer.h>

#include <cstdio>
#include <utility>

#include "common/base/clock.hpp"

namespace fogmap::view {

ViewRuntime::ViewRuntime(ViewConfig config, FeedTarget root, std::optional<FeedTarget> tracker, ViewOptions options)
    : options_(std::move(options)),
      live_(std::move(config)),
      hub_(options_.max_pages),
      registry_(std::make_shared<prometheus::Registry>()),
      messages_(prometheus::BuildCounter().Name("fogmap_view_messages_total").Help("Messages received, by stream").Register(*registry_)),
      refused_(prometheus::BuildCounter()
                   .Name("fogmap_view_refused_messages_total")
                   .Help("Messages that did not convert (malformed), by stream")
                   .Register(*registry_)),
      losses_(prometheus::BuildCounter().Name("fogmap_view_link_losses_total").Help("Streams lost, by stream").Register(*registry_)),
      pages_(prometheus::BuildGauge().Name("fogmap_view_pages").Help("Pages reading events now").Register(*registry_).Add({})),
      pages_refused_(prometheus::BuildCounter()
                         .Name("fogmap_view_pages_refused_total")
                         .Help("Pages refused because max_pages were reading")
                         .Register(*registry_)
                         .Add({})),
      events_published_(
          prometheus::BuildCounter().Name("fogmap_view_events_total").Help("Events published to the pages").Register(*registry_).Add({})),
      events_skipped_(prometheus::BuildCounter()
                          .Name("fogmap_view_events_skipped_total")
                          .Help("Events a page never received because a newer one of their kind came first (a slow page)")
                          .Register(*registry_)
                          .Add({})),
      log_("fogctl view: ", [](const std::string& line) { std::fprintf(stderr, "%s\n", line.c_str()); }, options_.now),
      root_target_(std::move(root)),
      tracker_target_(std::move(tracker)) {
  root_ = {false, root_target_.target, "connecting"};
  if (tracker_target_) tracker_ = LinkState{false, tracker_target_->target, "connecting"};
}

Expected<std::unique_ptr<ViewRuntime>> ViewRuntime::start(ViewConfig config, FeedTarget root, std::optional<FeedTarget> tracker,
                                                          ViewOptions options) {
  std::unique_ptr<ViewRuntime> runtime(new ViewRuntime(std::move(config), std::move(root), std::move(tracker), std::move(options)));
  ViewRuntime* self = runtime.get();
  {
    std::lock_guard lock(self->mutex_);
    self->hub_.publish(EventKind::kConfig, self->live_.configEvent());
    self->publishStatus();
  }
  WebServerOptions web = self->options_.web;
  web.metrics_text = [self] { return self->metricsText(); };
  auto server = WebServer::start(web, self->hub_);
  if (!server) return server.error();
  self->server_ = std::move(*server);
  FeedHandlers handlers;
  handlers.on_map = [self](GlobalMapMessage m) { self->onMap(m); };
  handlers.on_tracks = [self](tracking::TrackSnapshot s) { self->onTracks(s); };
  handlers.on_link = [self](Stream s, const LinkState& l) { self->onLink(s, l); };
  handlers.on_refused = [self](Stream s, const std::string& why) { self->onRefused(s, why); };
  self->feed_ = std::make_unique<ViewFeed>(self->root_target_, self->tracker_target_, std::move(handlers), self->options_.max_message_bytes,
                                           self->options_.idle_timeout);
  self->heartbeat_ = std::make_unique<Periodic>(
      [self] {
        self->feed_->checkIdle();
        self->log_.flush();
        std::lock_guard lock(self->mutex_);
        self->publishStatus();
      },
      self->options_.heartbeat);
  self->heartbeat_->start();
  return runtime;
}

ViewRuntime::~ViewRuntime() {
  if (heartbeat_) heartbeat_->stop();
  if (feed_) feed_->stop();
  log_.flush(true);
  server_.reset();  // stops the hub's readers first
}

void ViewRuntime::onMap(const GlobalMapMessage& global) {
  messages_.Add({{"stream", "root"}}).Increment();
  std::lock_guard lock(mutex_);
  hub_.publish(EventKind::kMap, live_.mapEvent(global));
}

void ViewRuntime::onTracks(const tracking::TrackSnapshot& snapshot) {
  messages_.Add({{"stream", "tracker"}}).Increment();
  std::lock_guard lock(mutex_);
  hub_.publish(EventKind::kTracks, live_.tracksEvent(snapshot));
}

void ViewRuntime::onLink(Stream stream, const LinkState& link) {
  std::lock_guard lock(mutex_);
  LinkState& state = stream == Stream::kRoot ? root_ : *tracker_;
  if (state.connected && !link.connected) losses_.Add({{"stream", streamName(stream)}}).Increment();
  state = link;
  publishStatus();
}

void ViewRuntime::onRefused(Stream stream, const std::string& why) {
  refused_.Add({{"stream", streamName(stream)}}).Increment();
  log_.note(std::string("malformed ") + (stream == Stream::kRoot ? "global map" : "track list"), why);
}

void ViewRuntime::publishStatus() { hub_.publish(EventKind::kStatus, live_.statusEvent(root_, tracker_, hub_.skipped(), options_.now())); }

std::string ViewRuntime::metricsText() {
  std::lock_guard lock(metrics_mutex_);
  pages_.Set(static_cast<double>(hub_.clients()));
  const auto add = [](prometheus::Counter& counter, std::uint64_t total, std::uint64_t& counted) {
    if (total > counted) counter.Increment(static_cast<double>(total - counted));
    counted = total;
  };
  add(pages_refused_, hub_.refused(), counted_refused_pages_);
  add(events_published_, hub_.published(), counted_published_);
  add(events_skipped_, hub_.skipped(), counted_skipped_);
  return prometheus::TextSerializer().Serialize(registry_->Collect());
}

}  // namespace fogmap::view
