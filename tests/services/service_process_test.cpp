// What every service process does before it knows its topology: its command line, and the one stop
// mechanism (SIGINT and SIGTERM blocked in every thread and taken by one waiter, which requests
// the stop that every loop waits on).
#include <gtest/gtest.h>

#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <future>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "common/base/clock.hpp"
#include "services/common/service_process.hpp"

namespace fogmap {
namespace {

using namespace std::chrono_literals;

std::optional<ServiceArgs> parse(std::vector<std::string> words, const std::set<std::string>& extra = {}) {
  words.insert(words.begin(), "service");
  std::vector<char*> argv;
  for (auto& w : words) argv.push_back(w.data());
  return parseServiceArgs(static_cast<int>(argv.size()), argv.data(), extra);
}

TEST(ServiceArgs, TopologyAndNodeAreRequiredAndOnlyTheServicesOwnFlagsAreTaken) {
  const auto args = parse({"--topology", "t.yaml", "--node", "edge-1", "--journal", "j"}, {"journal"});
  ASSERT_TRUE(args);
  EXPECT_EQ(args->topology, "t.yaml");
  EXPECT_EQ(args->node, "edge-1");
  EXPECT_EQ(args->extra.at("journal"), "j");
  EXPECT_FALSE(parse({"--topology", "t.yaml", "--node", "edge-1", "--journal", "j"}));
  EXPECT_FALSE(parse({"--topology", "t.yaml"}));
  EXPECT_FALSE(parse({"--topology", "t.yaml", "--node"}));
  EXPECT_FALSE(parse({"topology", "t.yaml", "--node", "n"}));
}

TEST(StopRequest, ASleepEndsAtItsTimeOrAtOnceWhenTheStopIsRequested) {
  StopRequest stop;
  EXPECT_TRUE(stop.sleepUntil(systemNowNs() - 1));  // already due
  EXPECT_FALSE(stop.requestedAt());
  auto sleeper = std::async(std::launch::async, [&] { return stop.sleepUntil(systemNowNs() + 3'600'000'000'000); });
  stop.request();
  EXPECT_FALSE(sleeper.get()) << "an hour's sleep ends with the request";
  EXPECT_TRUE(stop.requested());
  const auto at = stop.requestedAt();
  ASSERT_TRUE(at);
  stop.request();  // again: harmless, the first time stays
  EXPECT_EQ(stop.requestedAt(), at);
  EXPECT_FALSE(stop.sleepUntil(systemNowNs() + 3'600'000'000'000));
  stop.wait();  // returns at once
}

// The signal goes to the whole process, as `kill` and a container runtime send it: without the
// waiter it would kill the child (the default action), so the exit code proves it was taken.
void stopOnSignal(int signal) {
  StopRequest stop;
  StopSignals signals(stop);
  std::thread worker([&] { stop.wait(); });  // started after: inherits the mask
  ::kill(::getpid(), signal);
  worker.join();
  std::_Exit(stop.requested() ? 7 : 1);
}

TEST(StopSignalsDeathTest, SigtermAndSigintRequestTheStopInsteadOfKillingTheProcess) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(stopOnSignal(SIGTERM), testing::ExitedWithCode(7), "");
  EXPECT_EXIT(stopOnSignal(SIGINT), testing::ExitedWithCode(7), "");
}

TEST(StopSignals, TheWaiterEndsWithItsOwnerWithoutRequestingTheStop) {
  StopRequest stop;
  { StopSignals signals(stop); }  // joins its waiter, no signal having come
  EXPECT_FALSE(stop.requested());
}

}  // namespace
}  // namespace fogmap
