#include "services/common/service_process.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <string_view>
#include <thread>

#include "common/clock.hpp"

namespace fogmap {
namespace {

// The one global: a signal handler can reach nothing else. Lock-free, so safe to set there.
std::atomic<bool> g_stop{false};
static_assert(std::atomic<bool>::is_always_lock_free);

void setStop(int /*signal*/) { g_stop.store(true); }

}  // namespace

std::optional<ServiceArgs> parseServiceArgs(int argc, char** argv, const std::set<std::string>& extra_flags) {
  ServiceArgs args;
  for (int i = 1; i < argc; ++i) {
    const std::string_view flag = argv[i];
    if (i + 1 >= argc || flag.substr(0, 2) != "--") return std::nullopt;
    const std::string name(flag.substr(2));
    const std::string value = argv[++i];
    if (name == "topology") {
      args.topology = value;
    } else if (name == "node") {
      args.node = value;
    } else if (extra_flags.count(name) > 0) {
      args.extra[name] = value;
    } else {
      return std::nullopt;
    }
  }
  if (args.topology.empty() || args.node.empty()) return std::nullopt;
  return args;
}

bool wantsHelp(int argc, char** argv) {
  return argc == 2 && (std::string_view(argv[1]) == "--help" || std::string_view(argv[1]) == "-h");
}

void installStopFlag() {
  std::signal(SIGINT, setStop);
  std::signal(SIGTERM, setStop);
}

bool stopRequested() { return g_stop.load(); }

bool sleepUntilUnlessStopped(std::int64_t until_ns, std::int64_t poll_ns) {
  while (!stopRequested()) {
    const std::int64_t now_ns = systemNowNs();
    if (now_ns >= until_ns) return true;
    std::this_thread::sleep_for(std::chrono::nanoseconds(std::min(until_ns - now_ns, poll_ns)));
  }
  return false;
}

}  // namespace fogmap
