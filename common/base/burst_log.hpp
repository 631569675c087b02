#pragma once
// Logs that cannot flood: one line per reason per burst, with a count. The first event of a
// reason is written at once (with its detail); the rest of the burst is counted and written as one
// summary line when the reason has been quiet for `quiet`, or every `interval` while it goes on
// (a flood that never pauses still writes one line per interval per reason, not one per event).
// Pure: time comes from the injected clock, lines go to the injected sink; thread-safe.
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <string>

#include "common/base/clock.hpp"

namespace fogmap {

class BurstLog {
 public:
  using Sink = std::function<void(const std::string& line)>;
  // `prefix` leads every line (e.g. "tracker t1: "); `what` names the events ("refused").
  BurstLog(std::string prefix, Sink sink, NowNs now, std::chrono::milliseconds quiet = std::chrono::seconds(5),
           std::chrono::milliseconds interval = std::chrono::seconds(10));

  // One event of `reason`; `detail` is written only when it opens a burst.
  void note(const std::string& reason, const std::string& detail);
  // Writes the summaries of bursts that went quiet (call now and then, e.g. from a timer; note
  // does it too); with `all`, of every burst (shutdown).
  void flush(bool all = false);
  // Lines written so far (tests, and a metric if wanted).
  std::uint64_t linesWritten() const;

 private:
  struct Burst {
    std::int64_t last_ns = 0;     // latest event
    std::int64_t summary_ns = 0;  // the burst's opening line or latest summary
    std::uint64_t unreported = 0; // events since then, not yet written
    std::string latest;           // the latest event's detail
  };
  void summarise(const std::string& reason, Burst& burst, std::int64_t now_ns);
  void write(const std::string& line);

  std::string prefix_;
  Sink sink_;
  NowNs now_;
  std::int64_t quiet_ns_;
  std::int64_t interval_ns_;
  mutable std::mutex mutex_;
  std::map<std::string, Burst> bursts_;  // open bursts, by reason
  std::uint64_t lines_ = 0;
};

}  // namespace fogmap
