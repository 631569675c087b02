#include "harness/launcher.hpp"
#include "common/config/camera_node.hpp"
#include "common/config/topology_parse.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <fstream>
#include <iterator>
#include <optional>
#include <sstream>
#include <system_error>
#include <thread>

namespace fogmap::harness {

namespace {
std::atomic<bool> g_stop{false};
void onSignal(int) { g_stop = true; }
}  // namespace

void installStopHandlers() {
  struct sigaction sa {};
  sa.sa_handler = onSignal;
  ::sigaction(SIGINT, &sa, nullptr);
  ::sigaction(SIGTERM, &sa, nullptr);
}

bool stopRequested() { return g_stop.load(); }
void requestStop() { g_stop = true; }

std::filesystem::path binaryDir() {
  std::error_code ec;
  const auto self = std::filesystem::read_symlink("/proc/self/exe", ec);
  return ec ? std::filesystem::current_path() : self.parent_path();
}

namespace {

Expected<pid_t> spawn(const std::filesystem::path& binary, const std::vector<std::string>& args,
                      const std::filesystem::path& log, bool append = false) {
  std::error_code ec;
  if (!std::filesystem::exists(binary, ec)) return notFound("service binary not found: " + binary.string());
  const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | (append ? O_APPEND : O_TRUNC) | O_CLOEXEC, 0644);
  if (fd < 0) return ioError("cannot open log file " + log.string());
  std::vector<std::string> argv_storage{binary.string()};
  argv_storage.insert(argv_storage.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : argv_storage) argv.push_back(a.data());
  argv.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid < 0) {
    ::close(fd);
    return ioError("fork failed");
  }
  if (pid == 0) {
    ::dup2(fd, STDOUT_FILENO);
    ::dup2(fd, STDERR_FILENO);
    ::setpgid(0, 0);  // Ctrl-C on fogctl reaches fogctl only; it stops the services itself
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  ::close(fd);
  return pid;
}

}  // namespace

namespace {

// Field 22 of /proc/PID/stat, the start time in clock ticks after boot; nullopt when there is no
// such process. The command name (field 2) may hold spaces and parentheses: fields after the
// last ')' are counted.
std::optional<std::uint64_t> startTicks(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  if (!in) return std::nullopt;
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto paren = text.rfind(')');
  if (paren == std::string::npos) return std::nullopt;
  std::istringstream fields(text.substr(paren + 1));
  std::string field;
  for (int k = 3; k < 22; ++k) {
    if (!(fields >> field)) return std::nullopt;
  }
  std::uint64_t ticks = 0;
  if (!(fields >> ticks)) return std::nullopt;
  return ticks;
}

// The process's arguments, as the services were given them.
std::vector<std::string> commandLine(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/cmdline");
  std::vector<std::string> args;
  std::string arg;
  while (std::getline(in, arg, '\0')) args.push_back(arg);
  return args;
}

// Still the process fogctl started for `node`: the start time recorded (when there is one) and a
// command line that runs that node.
bool isStartedService(const RunningNode& node) {
  const auto ticks = startTicks(node.pid);
  if (!ticks || (node.start_ticks != 0 && *ticks != node.start_ticks)) return false;
  const auto args = commandLine(node.pid);
  for (std::size_t i = 0; i + 1 < args.size(); ++i) {
    if (args[i] == "--node" && args[i + 1] == node.name) return true;
  }
  return false;
}

// The pid still names the process that was started (before signalling it again).
bool sameProcess(const RunningNode& node) {
  if (node.start_ticks == 0) return true;
  const auto ticks = startTicks(node.pid);
  return ticks && *ticks == node.start_ticks;
}

}  // namespace

bool isRunning(pid_t pid) {
  int status = 0;
  const pid_t r = ::waitpid(pid, &status, WNOHANG);
  if (r == 0) return true;
  if (r == pid) return false;
  return ::kill(pid, 0) == 0;  // not our child (stopRecorded): probe it
}

namespace {
bool running(pid_t pid) { return isRunning(pid); }
}  // namespace

Expected<std::string> httpGet(const std::string& host, std::uint16_t port, const std::string& path,
                              std::chrono::milliseconds timeout) {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (fd < 0) return ioError("socket() failed");
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(port);
  if (::inet_pton(AF_INET, host.c_str(), &addr.sin_addr) != 1) {
    ::close(fd);
    return invalidArgument("not an IPv4 address: " + host);
  }
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  auto wait_for = [&](short events) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) return false;
    pollfd p{fd, events, 0};
    return ::poll(&p, 1, static_cast<int>(left.count())) == 1;
  };
  std::string response;
  bool ok = false;
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0 || errno == EINPROGRESS) {
    int err = 0;
    socklen_t len = sizeof err;
    if (wait_for(POLLOUT) && ::getsockopt(fd, SOL_SOCKET, SO_ERROR, &err, &len) == 0 && err == 0) {
      const std::string request = "GET " + path + " HTTP/1.0\r\nHost: " + host + "\r\n\r\n";
      if (::send(fd, request.data(), request.size(), MSG_NOSIGNAL) == static_cast<ssize_t>(request.size())) {
        char buffer[65536];
        while (wait_for(POLLIN)) {
          const ssize_t n = ::recv(fd, buffer, sizeof buffer, 0);
          if (n <= 0) {
            ok = n == 0;
            break;
          }
          response.append(buffer, static_cast<std::size_t>(n));
        }
      }
    }
  }
  ::close(fd);
  if (!ok) return ioError("no HTTP answer from " + host + ":" + std::to_string(port) + path);
  const auto body = response.find("\r\n\r\n");
  if (response.rfind("HTTP/1.", 0) != 0 || body == std::string::npos) return ioError("malformed HTTP answer from " + host);
  if (response.find(" 200 ") > response.find("\r\n")) return ioError("HTTP error from " + host + ": " + response.substr(0, response.find("\r\n")));
  return response.substr(body + 4);
}

namespace {

// Aggregators and trackers serve the other nodes: they start first.
bool serves(const NodeConfig& node) { return node.role == Role::kAggregator || node.role == Role::kTracker; }

// The program and arguments that run `node` of `topology_file` (absolute): its service binary
// beside fogctl, behind the node's prefix when StartOptions gives one.
std::vector<std::string> nodeCommand(const std::filesystem::path& topology_file, const NodeConfig& node,
                                     const StartOptions& options) {
  std::vector<std::string> command;
  if (const auto prefix = options.prefixes.find(node.name); prefix != options.prefixes.end()) {
    command = prefix->second;
  }
  command.push_back((binaryDir() / serviceName(node.role)).string());
  command.insert(command.end(), {"--topology", topology_file.string(), "--node", node.name});
  if (node.role == Role::kEdge && !options.journal_dir.empty()) {
    command.push_back("--journal");
    command.push_back((options.journal_dir / (node.name + ".journal")).string());
  }
  return command;
}

std::filesystem::path logFile(const std::filesystem::path& state_dir, const NodeConfig& node) {
  return state_dir / "logs" / (node.name + ".log");
}

// The nodes startCluster starts, in its order: servers (aggregators, trackers) before their
// clients (edges, cameras); only those StartOptions::only names when it names any.
Expected<std::vector<const NodeConfig*>> startOrder(const std::filesystem::path& topology_file, const TopologyConfig& topology,
                                                    const StartOptions& options) {
  for (const std::string& name : options.only) {
    if (topology.find(name) == nullptr) return notFound("no node '" + name + "' in " + topology_file.string());
  }
  const auto starts = [&](const NodeConfig& n) {
    return options.only.empty() || std::find(options.only.begin(), options.only.end(), n.name) != options.only.end();
  };
  std::vector<const NodeConfig*> order;
  for (const bool servers : {true, false}) {
    for (const auto& n : topology.nodes) {
      if (serves(n) == servers && starts(n)) order.push_back(&n);
    }
  }
  return order;
}

// The topology file as the services are given it: absolute, so that they find it from any directory.
Expected<std::filesystem::path> absoluteTopologyFile(const std::filesystem::path& topology_file) {
  std::error_code ec;
  const auto absolute = std::filesystem::absolute(topology_file, ec);
  if (ec || topology_file.empty()) {
    return invalidArgument("topology file '" + topology_file.string() + "': cannot make the path absolute: " +
                           (ec ? ec.message() : std::string("it is empty")));
  }
  return absolute;
}

// Forks the service for `node` (its log under state_dir/logs, truncated unless `append`).
Expected<RunningNode> spawnNode(const Cluster& cluster, const NodeConfig& node, const StartOptions& options, bool append) {
  const std::vector<std::string> command = nodeCommand(cluster.topology_file, node, options);
  const auto log = logFile(cluster.state_dir, node);
  auto pid = spawn(command.front(), std::vector<std::string>(command.begin() + 1, command.end()), log, append);
  if (!pid) return pid.error();
  // The child's start time is fixed at fork, so reading it now is reading the service's.
  return RunningNode{node.name, *pid, log, startTicks(*pid).value_or(0)};
}

// Waits until the node serves /metrics; an error when it exits first or the deadline passes.
Expected<bool> waitReady(const NodeConfig& node, const RunningNode& running_node,
                         std::chrono::steady_clock::time_point deadline) {
  while (true) {
    if (httpGet(node.host, node.metrics_port, "/metrics", std::chrono::milliseconds(500)).ok()) return true;
    if (!running(running_node.pid)) {
      return Error{ErrorCode::kInternal, "node " + node.name + " exited during start; see " + running_node.log.string()};
    }
    if (std::chrono::steady_clock::now() > deadline) {
      return Error{ErrorCode::kInternal, "node " + node.name + " not ready within the timeout; see " + running_node.log.string()};
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
}

}  // namespace

Expected<RunningNode> restartNode(Cluster& cluster, const TopologyConfig& topology, const std::string& name,
                                  std::chrono::milliseconds timeout, const StartOptions& options) {
  const NodeConfig* node = topology.find(name);
  const auto entry = std::find_if(cluster.nodes.begin(), cluster.nodes.end(), [&](const RunningNode& r) { return r.name == name; });
  if (node == nullptr || entry == cluster.nodes.end()) return notFound("no node '" + name + "' in the cluster");
  if (entry->pid > 0 && running(entry->pid)) return invalidArgument("node '" + name + "' is still running");
  if (options.journal_dir.empty() == false && node->role == Role::kEdge) {
    // The restarted edge appends to the journal of its previous life: keep it aside first.
    std::error_code ec;
    const auto journal = options.journal_dir / (name + ".journal");
    for (int life = 1; life < 1000; ++life) {
      const auto kept = options.journal_dir / (name + ".journal." + std::to_string(life));
      if (!std::filesystem::exists(kept, ec)) {
        std::filesystem::rename(journal, kept, ec);
        break;
      }
    }
  }
  auto started = spawnNode(cluster, *node, options, /*append=*/true);
  if (!started) return started.error();
  *entry = *started;
  auto ready = waitReady(*node, *entry, std::chrono::steady_clock::now() + timeout);
  if (!ready) return ready.error();
  return *entry;
}

bool stopNodes(const std::vector<RunningNode>& nodes, std::chrono::milliseconds grace) {
  std::vector<const RunningNode*> signalled;
  for (const RunningNode& n : nodes) {
    if (n.pid > 0 && running(n.pid) && sameProcess(n)) {
      ::kill(n.pid, SIGTERM);
      signalled.push_back(&n);
    }
  }
  const auto deadline = std::chrono::steady_clock::now() + grace;
  const auto any_running = [&] {
    return std::any_of(signalled.begin(), signalled.end(), [](const RunningNode* n) { return running(n->pid); });
  };
  while (any_running() && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  bool all_exited = true;
  for (const RunningNode* n : signalled) {
    if (!running(n->pid)) continue;
    all_exited = false;
    ::kill(n->pid, SIGKILL);
    ::waitpid(n->pid, nullptr, 0);
  }
  return all_exited;
}

bool isDevice(const std::filesystem::path& source) { return source.string().rfind("/dev/", 0) == 0; }

std::vector<NodeFile> inputFiles(const NodeConfig& node) {
  std::vector<NodeFile> files;
  if (node.sensor) {
    // A simulated LiDAR reads its scene file ("sim" is no path); a recorded one its scans.
    if (node.sensor->simulated()) {
      files.push_back({node.sensor->scene, "sensor.scene", node.name + "'s scene"});
    } else {
      files.push_back({node.sensor->source, "sensor.source", node.name + "'s sensor source"});
    }
  }
  if (node.camera) {
    const CameraNodeConfig& c = *node.camera;
    if (c.simulated()) {
      files.push_back({c.scene, "camera.scene", node.name + "'s scene"});
    } else if (!isDevice(c.source)) {
      files.push_back({c.source, "camera.source", node.name + "'s camera source"});
    }
    if (!c.truth) {
      const camera::DetectorConfig& d = c.detector;
      if (d.kind == camera::DetectorKind::kCascade) {
        files.push_back({d.cascade.cascade_path, "camera.detector.cascade.cascade_path", node.name + "'s cascade"});
      }
      if (d.kind == camera::DetectorKind::kDnn) {
        files.push_back({d.dnn.model_path, "camera.detector.dnn.model_path", node.name + "'s model"});
        if (!d.dnn.config_path.empty()) {
          files.push_back({d.dnn.config_path, "camera.detector.dnn.config_path", node.name + "'s model configuration"});
        }
        files.push_back({d.dnn.names_path, "camera.detector.dnn.names_path", node.name + "'s class names"});
      }
    }
  }
  return files;
}

Status checkStartable(const TopologyConfig& topology) {
  for (const NodeConfig& node : topology.nodes) {
    const std::string where = "node '" + node.name + "': ";
    // The detection service's own check, with its words (services/detection/main.cpp).
    if (node.camera && !node.camera->truth) {
      if (const Status s = camera::validate(node.camera->detector); !s) {
        return Error{s.error().code, where + "camera.detector." + s.error().message};
      }
    }
    for (const NodeFile& file : inputFiles(node)) {
      if (file.path.empty()) return invalidArgument(where + file.field + ": is required");
      std::error_code ec;
      const bool present = std::filesystem::exists(file.path, ec);
      if (ec && ec != std::errc::no_such_file_or_directory) {
        return ioError(where + file.field + ": cannot check " + file.path.string() + ": " + ec.message());
      }
      if (!present) return notFound(where + file.field + ": no such file or directory: " + file.path.string());
    }
  }
  return {};
}

Expected<TopologyConfig> loadStartableTopology(const std::filesystem::path& file) {
  auto topology = loadTopology(file);
  if (!topology) return topology.error();
  if (const Status startable = checkStartable(*topology); !startable) {
    return Error{startable.error().code, file.string() + ": " + startable.error().message};
  }
  return topology;
}

Expected<std::vector<PlannedNode>> planCluster(const std::filesystem::path& topology_file, const TopologyConfig& topology,
                                               const std::filesystem::path& state_dir, const StartOptions& options) {
  if (const Status startable = checkStartable(topology); !startable) return startable.error();
  const auto absolute = absoluteTopologyFile(topology_file);
  if (!absolute) return absolute.error();
  const auto order = startOrder(topology_file, topology, options);
  if (!order) return order.error();
  std::vector<PlannedNode> plan;
  for (const NodeConfig* node : *order) {
    plan.push_back({node->name, node->role, nodeCommand(*absolute, *node, options), logFile(state_dir, *node)});
  }
  return plan;
}

Expected<Cluster> startCluster(const std::filesystem::path& topology_file, const TopologyConfig& topology,
                               const std::filesystem::path& state_dir, std::chrono::milliseconds timeout,
                               const StartOptions& options) {
  Cluster cluster;
  const auto absolute = absoluteTopologyFile(topology_file);
  if (!absolute) return absolute.error();
  cluster.topology_file = *absolute;
  cluster.state_dir = state_dir;
  const auto started_order = startOrder(topology_file, topology, options);
  if (!started_order) return started_order.error();
  const std::vector<const NodeConfig*>& order = *started_order;
  std::error_code ec;
  std::filesystem::create_directories(state_dir / "logs", ec);
  if (ec) return ioError("cannot create " + (state_dir / "logs").string() + ": " + ec.message());
  if (!options.journal_dir.empty()) {
    std::filesystem::create_directories(options.journal_dir, ec);
    if (ec) return ioError("cannot create " + options.journal_dir.string() + ": " + ec.message());
  }
  std::ofstream pids(state_dir / "pids");
  // Aggregators and trackers first, ready (they listen before /metrics answers), then the edges and
  // cameras: an edge then
  // reaches its parent at once instead of backing off, and whoever watches the root (the
  // aggregators_ready hook) is subscribed before the first map can come.
  // Ready = every service answers on /metrics (servers listen before metrics start).
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  const auto first_edge = std::find_if(order.begin(), order.end(), [](const NodeConfig* n) { return !serves(*n); });
  for (const auto& [from, to] : {std::pair{order.begin(), first_edge}, std::pair{first_edge, order.end()}}) {
    for (auto n = from; n != to; ++n) {
      auto started = spawnNode(cluster, **n, options, /*append=*/false);
      if (!started) {
        stopCluster(cluster, std::chrono::milliseconds(2000));
        return started.error();
      }
      cluster.nodes.push_back(*started);
      pids << started->pid << ' ' << (*n)->name << ' ' << started->start_ticks << '\n';
      pids.flush();
    }
    for (auto n = from; n != to; ++n) {
      const auto it = std::find_if(cluster.nodes.begin(), cluster.nodes.end(), [&](const RunningNode& r) { return r.name == (*n)->name; });
      auto ready = waitReady(**n, *it, deadline);
      if (!ready) {
        stopCluster(cluster, std::chrono::milliseconds(2000));
        return ready.error();
      }
    }
    if (to == first_edge && options.aggregators_ready) options.aggregators_ready();
  }
  pids.close();
  return cluster;
}

void stopCluster(const Cluster& cluster, std::chrono::milliseconds grace) {
  // Edges first (they flush to their parents), then aggregators from the leaves up.
  for (auto it = cluster.nodes.rbegin(); it != cluster.nodes.rend(); ++it) {
    if (it->pid > 0 && sameProcess(*it)) ::kill(it->pid, SIGTERM);
  }
  const auto deadline = std::chrono::steady_clock::now() + grace;
  for (const auto& n : cluster.nodes) {
    while (n.pid > 0 && running(n.pid) && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    if (n.pid > 0 && running(n.pid) && sameProcess(n)) {
      ::kill(n.pid, SIGKILL);
      ::waitpid(n.pid, nullptr, 0);
    }
  }
  std::error_code ec;
  std::filesystem::remove(cluster.state_dir / "pids", ec);
}

Expected<StopReport> stopRecorded(const std::filesystem::path& state_dir, std::chrono::milliseconds grace) {
  const auto file = state_dir / "pids";
  std::ifstream in(file);
  if (!in) return notFound("no running cluster recorded in " + file.string());
  StopReport report;
  Cluster cluster;
  cluster.state_dir = state_dir;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    if (line.empty()) continue;
    std::istringstream fields(line);
    RunningNode node;
    if (!(fields >> node.pid >> node.name) || node.pid <= 0) {
      return invalidArgument(file.string() + ":" + std::to_string(number) + ": not 'PID NODE [START_TICKS]'");
    }
    fields >> node.start_ticks;  // absent in records of an older fogctl: the command line decides
    if (!startTicks(node.pid)) {
      report.gone.push_back(node);
    } else if (!isStartedService(node)) {
      report.replaced.push_back(node);
    } else {
      report.stopped.push_back(node);
      cluster.nodes.push_back(node);
    }
  }
  stopCluster(cluster, grace);
  return report;
}

bool allRunning(const Cluster& cluster) {
  for (const auto& n : cluster.nodes) {
    if (!running(n.pid)) return false;
  }
  return true;
}

}  // namespace fogmap::harness
