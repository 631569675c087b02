// The event hub: newest event per kind, skips counted, a bounded number of readers, and a publisher
// that never waits for a reader.
#include <gtest/gtest.h>

#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include "view/event_hub.hpp"

namespace fogmap::view {
namespace {

using namespace std::chrono_literals;

TEST(EventHub, AReaderGetsTheNewestEventOfEachKindInKindOrderAndSkipsAreCounted) {
  EventHub hub(4);
  auto reader = hub.join();
  ASSERT_TRUE(reader);
  hub.publish(EventKind::kMap, "m1");
  hub.publish(EventKind::kConfig, "c1");
  auto events = reader->next(0ms);
  ASSERT_EQ(events.size(), 2U);
  EXPECT_EQ(events[0].kind, EventKind::kConfig);  // the page needs the config before the map
  EXPECT_EQ(*events[1].data, "m1");
  EXPECT_EQ(hub.skipped(), 0U);
  // Three maps and a track list while the reader was busy: it gets the newest map, 2 skipped.
  hub.publish(EventKind::kMap, "m2");
  hub.publish(EventKind::kMap, "m3");
  hub.publish(EventKind::kTracks, "t1");
  hub.publish(EventKind::kMap, "m4");
  events = reader->next(0ms);
  ASSERT_EQ(events.size(), 2U);
  EXPECT_EQ(*events[0].data, "m4");
  EXPECT_EQ(events[0].version, 4U);
  EXPECT_EQ(*events[1].data, "t1");
  EXPECT_EQ(hub.skipped(), 2U);
  EXPECT_TRUE(reader->next(0ms).empty());  // nothing new
  EXPECT_EQ(hub.published(), 6U);
  EXPECT_EQ(hub.delivered(), 4U);
  // A reader that joins late starts at the newest: nothing is counted skipped for it.
  auto late = hub.join();
  events = late->next(0ms);
  ASSERT_EQ(events.size(), 3U);
  EXPECT_EQ(hub.skipped(), 2U);
}

TEST(EventHub, ReadersBeyondTheBoundAreRefusedAndALeavingReaderFreesItsPlace) {
  EventHub hub(2);
  auto a = hub.join();
  auto b = hub.join();
  ASSERT_TRUE(a && b);
  EXPECT_FALSE(hub.join());
  EXPECT_EQ(hub.refused(), 1U);
  EXPECT_EQ(hub.clients(), 2U);
  a.reset();
  EXPECT_EQ(hub.clients(), 1U);
  EXPECT_TRUE(hub.join());
}

TEST(EventHub, AWaitingReaderWakesForAnEventAndStopEndsEveryWait) {
  EventHub hub(2);
  auto reader = hub.join();
  std::vector<Event> got;
  std::thread waiter([&] { got = reader->next(60s); });
  hub.publish(EventKind::kStatus, "s");
  waiter.join();  // woken by the event, long before 60 s
  ASSERT_EQ(got.size(), 1U);
  std::thread stopped([&] { got = reader->next(60s); });
  hub.stop();
  stopped.join();
  EXPECT_TRUE(got.empty());
  EXPECT_TRUE(reader->stopped());
  EXPECT_FALSE(hub.join());
}

TEST(EventHub, APublisherNeverWaitsForAReaderThatDoesNotRead) {
  EventHub hub(2);
  auto idle = hub.join();  // never reads
  for (int k = 0; k < 100000; ++k) hub.publish(EventKind::kMap, std::to_string(k));
  // Memory stays one event per kind: the reader gets only the newest.
  const auto events = idle->next(0ms);
  ASSERT_EQ(events.size(), 1U);
  EXPECT_EQ(*events[0].data, "99999");
}

TEST(EventHub, AnEventIsOneServerSentEventsFrame) {
  Event e;
  e.kind = EventKind::kTracks;
  e.data = std::make_shared<const std::string>("{\"tracks\":[]}");
  EXPECT_EQ(sseFrame(e), "event: tracks\ndata: {\"tracks\":[]}\n\n");
}

}  // namespace
}  // namespace fogmap::view
