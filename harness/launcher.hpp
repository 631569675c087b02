#pragma once
// Starts and stops the services of a topology as local processes.
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include <sys/types.h>

#include "common/base/status.hpp"
#include "common/config/topology.hpp"

namespace fogmap::harness {

struct RunningNode {
  std::string name;
  pid_t pid = -1;
  std::filesystem::path log;
  // The process's start time (/proc/PID/stat, clock ticks after boot): with the pid, it names the
  // process even after the pid is reused. 0 when unknown (records of an older fogctl).
  std::uint64_t start_ticks = 0;
};

struct Cluster {
  std::filesystem::path topology_file;
  std::filesystem::path state_dir;  // logs/ and pids
  std::vector<RunningNode> nodes;
};

// SIGINT/SIGTERM set a flag that long-running commands poll (bounded waits everywhere).
void installStopHandlers();
bool stopRequested();
void requestStop();

// The directory holding fogctl, where the service binaries live too.
std::filesystem::path binaryDir();

struct StartOptions {
  // Edges record how each upload ended in journal_dir/NAME.journal (services/common/delivery_journal.hpp).
  std::filesystem::path journal_dir;  // empty: no journals
  // Per node, a command that runs the service (e.g. inside a network namespace: ip netns exec NS).
  std::map<std::string, std::vector<std::string>> prefixes;
  // Called once every aggregator is ready and before any edge starts (e.g. to subscribe to the root).
  std::function<void()> aggregators_ready;
  // When not empty, only these nodes start: the others run elsewhere (another host, or a test's
  // in-process server standing in for them).
  std::vector<std::string> only;
};

// A file a node reads besides the topology and its TLS files: where it is, the node's field that
// names it ("camera.detector.cascade.cascade_path") and what it is in messages ("cam-1's cascade").
struct NodeFile {
  std::filesystem::path path;
  std::string field;
  std::string what;
};
// An edge's scans or scene; a camera's frames or scene (not a V4L2 device) and, unless it replays
// the truth, its detector's model files. A path the topology leaves empty is listed empty.
std::vector<NodeFile> inputFiles(const NodeConfig& node);
// A camera source that is a device (/dev/videoN), kept as written by the topology, not a file.
bool isDevice(const std::filesystem::path& source);

// What the services check about their own nodes before they start, for every node at once and
// without starting or opening anything: each camera's detector (camera::validate: its values and
// model files) and every input file present. TLS files are left to the services (fogctl certs may
// make them after this). Errors name the node and its field, as the services do:
// "node 'cam-1': camera.detector.cascade.cascade_path: is required".
Status checkStartable(const TopologyConfig& topology);

// loadTopology, then checkStartable: what fogctl up, compose and faults read a topology with.
// Errors begin with the file's name.
Expected<TopologyConfig> loadStartableTopology(const std::filesystem::path& file);

// One service as startCluster starts it.
struct PlannedNode {
  std::string name;
  Role role = Role::kEdge;
  std::vector<std::string> command;  // the program and its arguments
  std::filesystem::path log;
};
// What startCluster would start, in its order (aggregators and trackers, then edges and cameras),
// once checkStartable passes; starts, creates and writes nothing (fogctl up --dry-run).
Expected<std::vector<PlannedNode>> planCluster(const std::filesystem::path& topology_file, const TopologyConfig& topology,
                                               const std::filesystem::path& state_dir, const StartOptions& options = {});

// Starts every node of the topology (the aggregators, and once they are ready the edges), logs under state_dir/logs, records the
// pids (with their start times) in state_dir/pids, and waits until every /metrics endpoint answers (bounded by timeout).
// On failure everything started is stopped again.
Expected<Cluster> startCluster(const std::filesystem::path& topology_file, const TopologyConfig& topology,
                               const std::filesystem::path& state_dir, std::chrono::milliseconds timeout,
                               const StartOptions& options = {});
// Starts one node of a running cluster again (after it was killed): a new process, its log
// appended to, its journal (if any) continued; waits until its /metrics answers. Replaces the
// node's entry in `cluster`.
Expected<RunningNode> restartNode(Cluster& cluster, const TopologyConfig& topology, const std::string& name,
                                  std::chrono::milliseconds timeout, const StartOptions& options = {});
// SIGTERM to every node given at once, SIGKILL to those still running after the grace period;
// reaps them. True when all exited by themselves within the grace period.
bool stopNodes(const std::vector<RunningNode>& nodes, std::chrono::milliseconds grace);
// SIGTERM, then SIGKILL after the grace period; reaps the children.
void stopCluster(const Cluster& cluster, std::chrono::milliseconds grace);
struct StopReport {
  std::vector<RunningNode> stopped;
  std::vector<RunningNode> gone;      // no process with the pid any more
  std::vector<RunningNode> replaced;  // the pid now names another process: left alone
};
// Stops the processes recorded in state_dir/pids by another fogctl invocation; only those that are
// still the services started (same start time, command line naming the node) are signalled.
Expected<StopReport> stopRecorded(const std::filesystem::path& state_dir, std::chrono::milliseconds grace);
// True while the process runs (reaps it when it has exited).
bool isRunning(pid_t pid);
// True when every process of the cluster is still running.
bool allRunning(const Cluster& cluster);

// A plain HTTP/1.0 GET of http://host:port/path on loopback; the body, or an error.
Expected<std::string> httpGet(const std::string& host, std::uint16_t port, const std::string& path,
                              std::chrono::milliseconds timeout);

}  // namespace fogmap::harness
