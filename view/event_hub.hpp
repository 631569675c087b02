#pragma once
// Hands the view's events to the browsers: one publisher (the feed), up to `max_clients` readers
// (one per open page), and never a queue. The hub keeps only the newest event of each kind; a
// reader sends what is newer than what it sent last, so a browser that reads slowly skips
// events (counted) and never holds the publisher or the other browsers back.
#include <array>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace fogmap::view {

// In the order a reader sends them when several are new: what the page needs first comes first.
enum class EventKind { kConfig = 0, kStatus = 1, kMap = 2, kTracks = 3 };
inline constexpr std::size_t kEventKinds = 4;
const char* eventName(EventKind kind);  // "config", "status", "map", "tracks"

struct Event {
  EventKind kind = EventKind::kStatus;
  std::uint64_t version = 0;  // 1 for the kind's first event, then one more per event
  std::shared_ptr<const std::string> data;
};

// One Server-Sent-Events frame: "event: NAME\ndata: DATA\n\n" (DATA holds no line break: JSON
// without indentation never does).
std::string sseFrame(const Event& event);

class EventHub {
 public:
  explicit EventHub(std::size_t max_clients);

  // Replaces the newest event of `kind`; wakes every reader.
  void publish(EventKind kind, std::string data);

  // A reader's place; it leaves when destroyed.
  class Reader {
   public:
    Reader(Reader&& other) noexcept;
    Reader& operator=(Reader&&) = delete;
    Reader(const Reader&) = delete;
    ~Reader();
    // The kinds with an event newer than this reader sent, newest only, in EventKind order; waits
    // up to `wait` for one. Empty: nothing new in time, or the hub stopped (stopped() says which).
    std::vector<Event> next(std::chrono::milliseconds wait);
    bool stopped() const;

   private:
    friend class EventHub;
    explicit Reader(EventHub* hub) : hub_(hub) {}
    EventHub* hub_;
    std::array<std::uint64_t, kEventKinds> sent_{};  // the version of each kind sent last
  };

  // A place for one more reader, or none when `max_clients` are reading (counted) or the hub stopped.
  std::optional<Reader> join();
  // Ends every reader's wait; join() refuses from now on.
  void stop();

  std::size_t clients() const;
  std::size_t maxClients() const { return max_clients_; }
  std::uint64_t refused() const;    // joins refused: max_clients were reading
  std::uint64_t published() const;  // events published
  std::uint64_t delivered() const;  // events handed to readers
  std::uint64_t skipped() const;    // events a reader never sent because a newer one of their kind came first

 private:
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  const std::size_t max_clients_;
  std::array<Event, kEventKinds> newest_{};
  std::size_t clients_ = 0;
  bool stopped_ = false;
  std::uint64_t refused_ = 0;
  std::uint64_t published_ = 0;
  std::uint64_t delivered_ = 0;
  std::uint64_t skipped_ = 0;
};

}  // namespace fogmap::view
