#include "view/event_hub.hpp"

#include <utility>

namespace fogmap::view {

const char* eventName(EventKind kind) {
  switch (kind) {
    case EventKind::kConfig: return "config";
    case EventKind::kStatus: return "status";
    case EventKind::kMap: return "map";
    case EventKind::kTracks: return "tracks";
  }
  return "status";
}

std::string sseFrame(const Event& event) {
  std::string frame = "event: ";
  frame += eventName(event.kind);
  frame += "\ndata: ";
  if (event.data) frame += *event.data;
  frame += "\n\n";
  return frame;
}

EventHub::EventHub(std::size_t max_clients) : max_clients_(max_clients) {
  for (std::size_t k = 0; k < kEventKinds; ++k) newest_[k].kind = static_cast<EventKind>(k);
}

void EventHub::publish(EventKind kind, std::string data) {
  {
    std::lock_guard lock(mutex_);
    Event& event = newest_[static_cast<std::size_t>(kind)];
    ++event.version;
    event.data = std::make_shared<const std::string>(std::move(data));
    ++published_;
  }
  changed_.notify_all();
}

std::optional<EventHub::Reader> EventHub::join() {
  std::lock_guard lock(mutex_);
  if (stopped_) return std::nullopt;
  if (clients_ >= max_clients_) {
    ++refused_;
    return std::nullopt;
  }
  ++clients_;
  return Reader(this);
}

void EventHub::stop() {
  {
    std::lock_guard lock(mutex_);
    stopped_ = true;
  }
  changed_.notify_all();
}

EventHub::Reader::Reader(Reader&& other) noexcept : hub_(std::exchange(other.hub_, nullptr)), sent_(other.sent_) {}

EventHub::Reader::~Reader() {
  if (hub_ == nullptr) return;
  std::lock_guard lock(hub_->mutex_);
  --hub_->clients_;
}

bool EventHub::Reader::stopped() const {
  std::lock_guard lock(hub_->mutex_);
  return hub_->stopped_;
}

std::vector<Event> EventHub::Reader::next(std::chrono::milliseconds wait) {
  EventHub& hub = *hub_;
  std::unique_lock lock(hub.mutex_);
  const auto fresh = [&] {
    for (std::size_t k = 0; k < kEventKinds; ++k) {
      if (hub.newest_[k].version > sent_[k]) return true;
    }
    return false;
  };
  hub.changed_.wait_for(lock, wait, [&] { return hub.stopped_ || fresh(); });
  std::vector<Event> out;
  if (hub.stopped_) return out;
  for (std::size_t k = 0; k < kEventKinds; ++k) {
    const Event& event = hub.newest_[k];
    if (event.version <= sent_[k]) continue;
    // A reader that has sent nothing of a kind starts at the newest: what came before it is not skipped.
    if (sent_[k] > 0) hub.skipped_ += event.version - sent_[k] - 1;
    sent_[k] = event.version;
    out.push_back(event);
  }
  hub.delivered_ += out.size();
  return out;
}

std::size_t EventHub::clients() const {
  std::lock_guard lock(mutex_);
  return clients_;
}
std::uint64_t EventHub::refused() const {
  std::lock_guard lock(mutex_);
  return refused_;
}
std::uint64_t EventHub::published() const {
  std::lock_guard lock(mutex_);
  return published_;
}
std::uint64_t EventHub::delivered() const {
  std::lock_guard lock(mutex_);
  return delivered_;
}
std::uint64_t EventHub::skipped() const {
  std::lock_guard lock(mutex_);
  return skipped_;
}

}  // namespace fogmap::view
