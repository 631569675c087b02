// The periodic thread (the aggregator's emitter, the tracker's tick) on time the test moves by
// hand: it runs once at start, then once per period that passes (never catching up on periods it
// slept through), at once when woken, and stops while it waits.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <vector>

#include "services/common/periodic.hpp"
#include "tests/support/manual_time.hpp"

namespace fogmap {
namespace {

using namespace std::chrono_literals;
using test_support::ManualTime;

// Work that records the clock at every run.
struct Runs {
  explicit Runs(ManualTime& time) : time(time) {}
  void operator()() {
    std::lock_guard lock(mutex);
    at_ns.push_back(time.now());
  }
  std::vector<std::int64_t> all() {
    std::lock_guard lock(mutex);
    return at_ns;
  }
  ManualTime& time;
  std::mutex mutex;
  std::vector<std::int64_t> at_ns;
};

TEST(Periodic, RunsAtStartThenOncePerPeriodThatPasses) {
  auto time = std::make_shared<ManualTime>(1000);
  Runs runs(*time);
  Periodic periodic([&] { runs(); }, 10ms, time);
  periodic.start();
  ASSERT_TRUE(time->awaitWaits(1));
  EXPECT_EQ(runs.all(), (std::vector<std::int64_t>{1000}));
  time->advance(9ms);  // not yet a period
  time->advance(1ms);
  ASSERT_TRUE(time->awaitWaits(2));
  EXPECT_EQ(runs.all(), (std::vector<std::int64_t>{1000, 1000 + 10'000'000}));
  // Three periods at once (a stalled process): one run, and the next period counts from it.
  time->advance(30ms);
  ASSERT_TRUE(time->awaitWaits(3));
  EXPECT_EQ(runs.all().size(), 3U);
  EXPECT_EQ(runs.all().back(), 1000 + 40'000'000);
  periodic.stop();
  EXPECT_EQ(time->waits(), (std::vector<std::chrono::nanoseconds>{10ms, 10ms, 10ms}));
}

TEST(Periodic, AWakeRunsTheWorkAtOnceWithoutAPeriodPassing) {
  auto time = std::make_shared<ManualTime>();
  Runs runs(*time);
  Periodic periodic([&] { runs(); }, 10ms, time);
  periodic.start();
  ASSERT_TRUE(time->awaitWaits(1));
  periodic.wake();
  ASSERT_TRUE(time->awaitWaits(2));
  EXPECT_EQ(runs.all(), (std::vector<std::int64_t>{0, 0}));
  // A wake while the work runs is not lost: the next wait ends at once.
  std::mutex gate;
  std::unique_lock held(gate);
  auto slow_time = std::make_shared<ManualTime>();
  int slow_runs = 0;
  Periodic slow(
      [&] {
        if (++slow_runs == 1) {
          std::lock_guard wait_for_the_test(gate);
        }
      },
      10ms, slow_time);
  slow.start();
  slow.wake();  // while the first run waits for the gate
  held.unlock();
  ASSERT_TRUE(slow_time->awaitWaits(2));
  EXPECT_EQ(slow_runs, 2);
  EXPECT_EQ(slow_time->now(), 0);
}

TEST(Periodic, StopEndsTheThreadWhileItWaitsAndStartRunsItAgain) {
  auto time = std::make_shared<ManualTime>();
  Runs runs(*time);
  Periodic periodic([&] { runs(); }, 1h, time);
  periodic.start();
  ASSERT_TRUE(time->awaitWaits(1));
  periodic.stop();  // returns although the clock never moves
  EXPECT_EQ(runs.all().size(), 1U);
  periodic.start();
  ASSERT_TRUE(time->awaitWaits(2));
  EXPECT_EQ(runs.all().size(), 2U);
}

TEST(Periodic, TheSteadyPacerEndsAWaitWhenInterrupted) {
  SteadyPacer pacer;
  pacer.interrupt();  // before the wait: not lost
  EXPECT_TRUE(pacer.waitFor(1h));
  EXPECT_FALSE(pacer.waitFor(0ms));
}

}  // namespace
}  // namespace fogmap
