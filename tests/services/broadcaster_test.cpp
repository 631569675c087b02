// The bounded broadcaster behind every Subscribe stream (the root's global maps, a tracker's
// tracks): each subscriber gets every message in order from its own bounded queue, a full queue
// loses its oldest (counted), a slow subscriber never holds the publisher or the others back, the
// number of subscribers is bounded (one more refused and counted), and a shutdown lets each read
// what was queued for it before its stream ends.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdint>
#include <future>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <variant>
#include <vector>

#include "services/common/broadcaster.hpp"

namespace fogmap {
namespace {

using namespace std::chrono_literals;

// Generous bound of a wait that a message or the shutdown ends at once; reached only by a broken
// broadcaster, which then fails instead of hanging.
constexpr auto kLongWait = 30s;

using IntBroadcaster = Broadcaster<int>;

IntBroadcaster::Subscription join(IntBroadcaster& broadcaster) {
  auto joined = broadcaster.subscribe();
  EXPECT_TRUE(std::holds_alternative<IntBroadcaster::Subscription>(joined));
  return std::move(std::get<IntBroadcaster::Subscription>(joined));
}

// Everything queued for `subscription` now.
std::vector<int> drain(IntBroadcaster::Subscription& subscription) {
  std::vector<int> out;
  for (auto next = subscription.next(0ms); next.message; next = subscription.next(0ms)) out.push_back(*next.message);
  return out;
}

TEST(Broadcaster, EverySubscriberGetsEveryMessageInOrder) {
  IntBroadcaster broadcaster(16, 32);
  auto first = join(broadcaster);
  auto second = join(broadcaster);
  for (int i = 1; i <= 3; ++i) broadcaster.publish(i);
  EXPECT_EQ(drain(first), (std::vector<int>{1, 2, 3}));
  EXPECT_EQ(drain(second), (std::vector<int>{1, 2, 3}));
  EXPECT_EQ(broadcaster.subscriberCount(), 2U);
  EXPECT_EQ(broadcaster.dropped(), 0U);
  const auto idle = first.next(0ms);
  EXPECT_FALSE(idle.message);
  EXPECT_FALSE(idle.ended);
}

TEST(Broadcaster, AFullQueueLosesItsOldestCountedAndTheOthersLoseNothing) {
  std::uint64_t reported = 0;
  IntBroadcaster broadcaster(2, 32, {[&](std::uint64_t n) { reported += n; }, {}});
  auto slow = join(broadcaster);
  auto fast = join(broadcaster);
  std::vector<int> fast_got;
  for (int i = 1; i <= 5; ++i) {
    broadcaster.publish(i);
    for (int m : drain(fast)) fast_got.push_back(m);
  }
  EXPECT_EQ(fast_got, (std::vector<int>{1, 2, 3, 4, 5}));
  EXPECT_EQ(drain(slow), (std::vector<int>{4, 5}));
  EXPECT_EQ(broadcaster.dropped(), 3U);
  EXPECT_EQ(reported, 3U);
}

TEST(Broadcaster, ASubscriberBusyWritingNeverHoldsThePublisherBack) {
  IntBroadcaster broadcaster(4, 32);
  auto stuck = join(broadcaster);
  std::promise<void> took_one;
  std::promise<void> release;
  std::thread writer([&] {
    const auto first = stuck.next(kLongWait);
    EXPECT_EQ(first.message, std::optional<int>(1));
    took_one.set_value();
    release.get_future().wait();  // its client does not read: the write blocks
  });
  broadcaster.publish(1);
  took_one.get_future().wait();
  // The publisher goes on while the writer is stuck; the stuck one's queue keeps its newest 4.
  for (int i = 2; i <= 100; ++i) broadcaster.publish(i);
  release.set_value();
  writer.join();
  EXPECT_EQ(drain(stuck), (std::vector<int>{97, 98, 99, 100}));
  EXPECT_EQ(broadcaster.dropped(), 95U);
}

TEST(Broadcaster, SubscribersBeyondTheBoundAreRefusedCountedAndALeaverMakesRoom) {
  int refusals = 0;
  IntBroadcaster broadcaster(16, 2, {{}, [&] { ++refusals; }});
  auto first = join(broadcaster);
  std::optional<IntBroadcaster::Subscription> second(join(broadcaster));
  auto third = broadcaster.subscribe();
  ASSERT_TRUE(std::holds_alternative<IntBroadcaster::Refusal>(third));
  EXPECT_EQ(std::get<IntBroadcaster::Refusal>(third), IntBroadcaster::Refusal::kFull);
  EXPECT_EQ(broadcaster.refused(), 1U);
  EXPECT_EQ(refusals, 1);
  second.reset();  // leaves
  EXPECT_EQ(broadcaster.subscriberCount(), 1U);
  auto fourth = join(broadcaster);
  EXPECT_EQ(broadcaster.subscriberCount(), 2U);
  EXPECT_EQ(broadcaster.refused(), 1U);
}

TEST(Broadcaster, ShutdownLetsEachSubscriberReadWhatWasQueuedThenEndsItsStream) {
  IntBroadcaster broadcaster(16, 32);
  std::optional<IntBroadcaster::Subscription> reader(join(broadcaster));
  broadcaster.publish(1);
  broadcaster.publish(2);
  // The shutdown returns once the subscriber has left, long before its drain bound.
  auto shutdown = std::async(std::launch::async, [&] { broadcaster.shutdown(kLongWait); });
  std::vector<int> got;
  for (;;) {
    const auto next = reader->next(kLongWait);
    if (next.ended) break;
    ASSERT_TRUE(next.message);
    got.push_back(*next.message);
  }
  EXPECT_EQ(got, (std::vector<int>{1, 2}));
  reader.reset();
  shutdown.get();
  auto late = broadcaster.subscribe();
  ASSERT_TRUE(std::holds_alternative<IntBroadcaster::Refusal>(late));
  EXPECT_EQ(std::get<IntBroadcaster::Refusal>(late), IntBroadcaster::Refusal::kShuttingDown);
  EXPECT_EQ(broadcaster.refused(), 0U) << "a refusal during shutdown is not one of the bound";
}

TEST(Broadcaster, ASubscriberThatDoesNotReadWithinTheDrainIsEndedWithItsQueueUnread) {
  IntBroadcaster broadcaster(16, 32);
  auto idle = join(broadcaster);
  broadcaster.publish(1);
  broadcaster.shutdown(0ms);  // returns at once: the subscriber is still there
  EXPECT_EQ(broadcaster.subscriberCount(), 1U);
  const auto next = idle.next(kLongWait);
  EXPECT_TRUE(next.ended);
  EXPECT_FALSE(next.message);
}

TEST(Broadcaster, PublishEachGivesEverySubscriberWhatItAskedFor) {
  Broadcaster<std::string, bool> broadcaster(16, 32);  // wants: upper case
  auto lower = std::get<0>(broadcaster.subscribe(false));
  auto upper = std::get<0>(broadcaster.subscribe(true));
  auto skips = std::get<0>(broadcaster.subscribe(true));
  int converted = 0;
  broadcaster.publishEach([&](bool wants_upper) -> std::optional<std::string> {
    ++converted;
    return wants_upper ? "MAP" : "map";
  });
  EXPECT_EQ(converted, 3);
  EXPECT_EQ(lower.next(0ms).message, std::optional<std::string>("map"));
  EXPECT_EQ(upper.next(0ms).message, std::optional<std::string>("MAP"));
  EXPECT_TRUE(upper.wants());
  // A subscriber left out of one message (an on-time-only subscriber and a late map) gets the next.
  broadcaster.publishEach([&](bool wants_upper) -> std::optional<std::string> {
    if (wants_upper) return std::nullopt;
    return "late";
  });
  broadcaster.publish("next");
  EXPECT_EQ(skips.next(0ms).message, std::optional<std::string>("MAP"));
  EXPECT_EQ(skips.next(0ms).message, std::optional<std::string>("next"));
  EXPECT_EQ(lower.next(0ms).message, std::optional<std::string>("late"));
}

}  // namespace
}  // namespace fogmap
