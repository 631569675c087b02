#pragma once
// One publisher, a bounded number of subscribers, each with its own bounded queue: what a
// Subscribe stream reads from (the root's global maps, a tracker's tracks).
//
// - At most `max_subscribers` at once (topology admission.max_subscribers): one more is refused and
//   counted, so subscribers that never read cannot hold memory without bound.
// - A subscriber's queue holds at most `queue_capacity` messages: publishing to a full one drops
//   its oldest (counted). The publisher only appends under a short lock, so a slow subscriber never
//   holds it or the other subscribers back.
// - shutdown(drain): new subscribers are refused; each subscriber still reads what was queued for
//   it, until its queue is empty or `drain` has passed, then its stream ends.
//
// `Message` is what a queue holds (share big ones: a std::shared_ptr); `Wants` what a subscriber
// asked for, which publishEach looks at to choose each one's message.
#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <utility>
#include <variant>
#include <vector>

namespace fogmap {

// Observers for the metrics (each may be empty), called outside the broadcaster's lock.
struct BroadcasterHooks {
  std::function<void(std::uint64_t n)> on_dropped;  // n messages dropped from full queues by one publish
  std::function<void()> on_refused;                 // a subscriber refused: max_subscribers were served
};

template <class Message, class Wants = std::monostate>
class Broadcaster {
  struct Queue {
    Wants wants;
    std::deque<Message> messages;
  };

 public:
  // Why subscribe() said no.
  enum class Refusal { kFull, kShuttingDown };

  // What Subscription::next found.
  struct Delivery {
    std::optional<Message> message;  // none: nothing came within the wait (or the stream ended)
    bool ended = false;              // shut down, and nothing more will be delivered: end the stream
  };

  // One subscriber's place; it leaves when the Subscription is destroyed.
  class Subscription {
   public:
    Subscription(Subscription&& other) noexcept
        : owner_(std::exchange(other.owner_, nullptr)), queue_(std::move(other.queue_)) {}
    Subscription& operator=(Subscription&&) = delete;
    Subscription(const Subscription&) = delete;
    ~Subscription() {
      if (owner_ != nullptr) owner_->leave(queue_);
    }

    // The oldest message queued for this subscriber, waiting up to `wait` for one (bounded, so that
    // the caller can look for a cancelled client).
    Delivery next(std::chrono::milliseconds wait) { return owner_->next(*queue_, wait); }
    const Wants& wants() const { return queue_->wants; }

   private:
    friend class Broadcaster;
    Subscription(Broadcaster* owner, std::shared_ptr<Queue> queue) : owner_(owner), queue_(std::move(queue)) {}

    Broadcaster* owner_;
    std::shared_ptr<Queue> queue_;
  };

  // `queue_capacity` is at least 1.
  Broadcaster(std::size_t queue_capacity, std::size_t max_subscribers, BroadcasterHooks hooks = {})
      : queue_capacity_(std::max<std::size_t>(1, queue_capacity)),
        max_subscribers_(max_subscribers),
        hooks_(std::move(hooks)) {}
  Broadcaster(const Broadcaster&) = delete;
  Broadcaster& operator=(const Broadcaster&) = delete;

  // A place for a new subscriber, or why not (a refusal for kFull is counted).
  std::variant<Subscription, Refusal> subscribe(Wants wants = {}) {
    {
      std::lock_guard lock(mutex_);
      if (shutting_down_) return Refusal::kShuttingDown;
      if (queues_.size() < max_subscribers_) {
        auto queue = std::make_shared<Queue>();
        queue->wants = std::move(wants);
        queues_.push_back(queue);
        return Subscription(this, std::move(queue));
      }
      ++refused_;
    }
    if (hooks_.on_refused) hooks_.on_refused();
    return Refusal::kFull;
  }

  // Queues `message` for every subscriber.
  void publish(const Message& message) {
    publishEach([&message](const Wants&) -> std::optional<Message> { return message; });
  }
  // Queues select(wants) for every subscriber, none where it returns std::nullopt. `select` runs
  // under the lock, so it must be quick (share what it converts between subscribers).
  template <class Select>
  void publishEach(Select&& select) {
    std::uint64_t dropped = 0;
    {
      std::lock_guard lock(mutex_);
      for (const auto& queue : queues_) {
        std::optional<Message> message = select(std::as_const(queue->wants));
        if (!message) continue;
        queue->messages.push_back(std::move(*message));
        while (queue->messages.size() > queue_capacity_) {
          queue->messages.pop_front();
          ++dropped;
        }
      }
      dropped_ += dropped;
    }
    published_.notify_all();
    if (dropped > 0 && hooks_.on_dropped) hooks_.on_dropped(dropped);
  }

  // Refuses new subscribers and ends every subscription once it has read what is queued for it, or
  // after `drain` at the most; returns when every subscriber has left or `drain` has passed.
  void shutdown(std::chrono::milliseconds drain) {
    std::unique_lock lock(mutex_);
    shutting_down_ = true;
    published_.notify_all();
    left_.wait_for(lock, drain, [this] { return queues_.empty(); });
    drain_expired_ = true;
    published_.notify_all();
  }

  std::size_t subscriberCount() const {
    std::lock_guard lock(mutex_);
    return queues_.size();
  }
  std::size_t maxSubscribers() const { return max_subscribers_; }
  // Messages dropped from full queues since construction.
  std::uint64_t dropped() const {
    std::lock_guard lock(mutex_);
    return dropped_;
  }
  // Subscribers refused because max_subscribers were served, since construction.
  std::uint64_t refused() const {
    std::lock_guard lock(mutex_);
    return refused_;
  }

 private:
  Delivery next(Queue& queue, std::chrono::milliseconds wait) {
    std::unique_lock lock(mutex_);
    published_.wait_for(lock, wait, [&] { return shutting_down_ || !queue.messages.empty(); });
    // What was published before the shutdown is still delivered, within the drain time.
    if (shutting_down_ && (queue.messages.empty() || drain_expired_)) return {std::nullopt, true};
    if (queue.messages.empty()) return {};
    Delivery delivery{std::move(queue.messages.front()), false};
    queue.messages.pop_front();
    return delivery;
  }

  void leave(const std::shared_ptr<Queue>& queue) {
    {
      std::lock_guard lock(mutex_);
      std::erase(queues_, queue);
    }
    left_.notify_all();
  }

  const std::size_t queue_capacity_;
  const std::size_t max_subscribers_;
  const BroadcasterHooks hooks_;
  mutable std::mutex mutex_;
  std::condition_variable published_;  // a message queued, or the shutdown began or its drain ended
  std::condition_variable left_;       // a subscriber left
  std::vector<std::shared_ptr<Queue>> queues_;
  std::uint64_t dropped_ = 0;
  std::uint64_t refused_ = 0;
  bool shutting_down_ = false;
  bool drain_expired_ = false;
};

}  // namespace fogmap
