#pragma once
// What every service's composition root does the same way: read its command line (--topology FILE
// --node NAME, and the few flags a service adds), and stop on SIGINT or SIGTERM through one flag
// that its loops poll.
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>

namespace fogmap {

struct ServiceArgs {
  std::string topology;
  std::string node;
  std::map<std::string, std::string> extra;  // the service's own flags, without "--"
};

// "--flag value" pairs: --topology and --node are required, `extra_flags` (names without "--")
// allowed; nothing when anything else is given or a value is missing.
std::optional<ServiceArgs> parseServiceArgs(int argc, char** argv, const std::set<std::string>& extra_flags = {});
// True when the only argument is --help or -h.
bool wantsHelp(int argc, char** argv);

// SIGINT and SIGTERM set the stop flag (the handler does nothing else).
void installStopFlag();
bool stopRequested();
// Sleeps until the system clock reaches `until_ns`, waking at least every `poll_ns` so that a stop
// is seen promptly; false when a stop was requested.
bool sleepUntilUnlessStopped(std::int64_t until_ns, std::int64_t poll_ns = 50'000'000);

}  // namespace fogmap
