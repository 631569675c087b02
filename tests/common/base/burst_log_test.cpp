// BurstLog: one line per reason per burst, with the count, on an injected clock.
#include "common/base/burst_log.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace fogmap {
namespace {

using namespace std::chrono_literals;

struct Fixture {
  std::int64_t now = 1'000'000'000;
  std::vector<std::string> lines;
  BurstLog log{"t1: ", [this](const std::string& line) { lines.push_back(line); }, [this] { return now; }, 5s, 10s};
  void advance(std::chrono::milliseconds d) { now += std::chrono::duration_cast<std::chrono::nanoseconds>(d).count(); }
};

TEST(BurstLog, FirstEventIsWrittenWithItsDetailTheRestAreCounted) {
  Fixture f;
  f.log.note("late", "frame of epoch 7");
  for (int i = 0; i < 999; ++i) {
    f.advance(1ms);
    f.log.note("late", "frame of epoch " + std::to_string(8 + i));
  }
  ASSERT_EQ(f.lines.size(), 1U);
  EXPECT_EQ(f.lines[0].rfind("t1: late: frame of epoch 7", 0), 0U) << f.lines[0];
  // Quiet for the quiet time: the burst's summary names the count and the latest detail.
  f.advance(5s);
  f.log.flush();
  ASSERT_EQ(f.lines.size(), 2U);
  EXPECT_NE(f.lines[1].find("late: 999 more"), std::string::npos) << f.lines[1];
  EXPECT_NE(f.lines[1].find("epoch 1006"), std::string::npos) << f.lines[1];
  // Nothing more to say.
  f.advance(60s);
  f.log.flush();
  EXPECT_EQ(f.lines.size(), 2U);
}

TEST(BurstLog, ReasonsHaveTheirOwnBursts) {
  Fixture f;
  f.log.note("late", "a");
  f.log.note("early", "b");
  f.log.note("late", "c");
  f.log.note("early", "d");
  ASSERT_EQ(f.lines.size(), 2U);
  f.log.flush(true);
  EXPECT_EQ(f.lines.size(), 4U);
  EXPECT_NE(f.lines[2].find("1 more"), std::string::npos);
  EXPECT_NE(f.lines[3].find("1 more"), std::string::npos);
}

TEST(BurstLog, AFloodThatNeverPausesWritesOneLinePerInterval) {
  Fixture f;
  // 65,000 events in 10 s, as a hostile client sent: at most a line per interval, plus the first.
  for (int i = 0; i < 65'000; ++i) {
    f.log.note("malformed", "x");
    f.now += 10'000'000'000 / 65'000;
  }
  EXPECT_LE(f.lines.size(), 2U);
  std::uint64_t counted = 0;
  f.log.flush(true);
  for (std::size_t i = 1; i < f.lines.size(); ++i) {
    const auto at = f.lines[i].find("malformed: ");
    ASSERT_NE(at, std::string::npos);
    counted += std::stoull(f.lines[i].substr(at + 11));
  }
  EXPECT_EQ(counted, 64'999U) << "every event after the first is in a summary";
  EXPECT_EQ(f.log.linesWritten(), f.lines.size());
}

TEST(BurstLog, ABurstAfterQuietOpensWithItsDetailAgain) {
  Fixture f;
  f.log.note("late", "first");
  f.advance(6s);
  f.log.note("late", "second");
  ASSERT_EQ(f.lines.size(), 2U);
  EXPECT_NE(f.lines[1].find("second"), std::string::npos);
}

}  // namespace
}  // namespace fogmap
