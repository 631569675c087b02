#include "harness/netns.hpp"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <sstream>

namespace fogmap::harness {

namespace {

constexpr auto kProgramTimeout = std::chrono::seconds(15);
constexpr std::size_t kStderrKept = 400;  // characters of a failed command's stderr in its error

// What the child wrote to stderr, read until it closes it (exits) or the deadline passes.
// False when the deadline passed first.
bool readUntilClosed(int fd, std::string& text, std::chrono::steady_clock::time_point deadline) {
  char buffer[1024];
  while (true) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) return false;
    pollfd p{fd, POLLIN, 0};
    const int ready = ::poll(&p, 1, static_cast<int>(left.count()));
    if (ready < 0 && errno == EINTR) continue;
    if (ready <= 0) return false;
    const ssize_t n = ::read(fd, buffer, sizeof buffer);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return true;
    if (text.size() < kStderrKept) text.append(buffer, std::min<std::size_t>(static_cast<std::size_t>(n), kStderrKept - text.size()));
  }
}

std::string trimmed(std::string text) {
  std::replace(text.begin(), text.end(), '\n', ' ');
  while (!text.empty() && text.back() == ' ') text.pop_back();
  return text;
}

}  // namespace

std::string findProgram(const std::string& name) {
  std::string path = std::getenv("PATH") != nullptr ? std::getenv("PATH") : "";
  path += ":/usr/sbin:/sbin";
  std::istringstream dirs(path);
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    if (dir.empty()) continue;
    const auto candidate = std::filesystem::path(dir) / name;
    if (::access(candidate.c_str(), X_OK) == 0) return candidate.string();
  }
  return {};
}

Status runProgram(const std::vector<std::string>& argv) {
  std::string line;
  for (const auto& a : argv) line += (line.empty() ? "" : " ") + a;
  const std::string program = findProgram(argv.at(0));
  if (program.empty()) return notFound("'" + argv[0] + "' is not installed");
  std::vector<std::string> storage = argv;
  std::vector<char*> args;
  for (auto& a : storage) args.push_back(a.data());
  args.push_back(nullptr);
  int err[2];
  if (::pipe2(err, O_CLOEXEC) != 0) return ioError("pipe failed for: " + line);
  const pid_t pid = ::fork();
  if (pid < 0) {
    ::close(err[0]);
    ::close(err[1]);
    return ioError("fork failed for: " + line);
  }
  if (pid == 0) {
    const int null = ::open("/dev/null", O_WRONLY);
    if (null >= 0) ::dup2(null, STDOUT_FILENO);
    ::dup2(err[1], STDERR_FILENO);
    ::execv(program.c_str(), args.data());
    ::_exit(127);
  }
  ::close(err[1]);
  std::string stderr_text;
  const bool closed = readUntilClosed(err[0], stderr_text, std::chrono::steady_clock::now() + kProgramTimeout);
  ::close(err[0]);
  if (!closed) ::kill(pid, SIGKILL);  // hung: bounded like every wait here
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (!closed) return ioError("command timed out after " + std::to_string(kProgramTimeout.count()) + " s: " + line);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    const std::string said = trimmed(stderr_text);
    return ioError("command failed: " + line + (said.empty() ? "" : " (" + said + ")"));
  }
  return {};
}

Expected<NetnsLink> NetnsLink::create(unsigned tag) {
  const unsigned n = tag % 250U;
  return make("fogmap-" + std::to_string(tag), "fmh" + std::to_string(tag % 100000U), "fmn" + std::to_string(tag % 100000U),
              "10.213." + std::to_string(n) + ".", 1, /*check_iptables=*/true);
}

Expected<NetnsLink> NetnsLink::create(unsigned tag, PairAddress address) {
  if (address.octet > 255 || address.index >= kPairsPerOctet) {
    return invalidArgument("no pair " + std::to_string(address.index) + " in octet " + std::to_string(address.octet) +
                           " of the address plan (octet < 256, index < " + std::to_string(kPairsPerOctet) + ")");
  }
  // Interface names have at most 15 characters: fmh + 5 digits + p + 2 digits.
  const std::string id = std::to_string(tag % 100000U) + "p" + std::to_string(address.index);
  return make("fogmap-" + std::to_string(tag) + "-" + std::to_string(address.index), "fmh" + id, "fmn" + id,
              "10.213." + std::to_string(address.octet) + ".", 4 * address.index + 1, /*check_iptables=*/false);
}

Expected<NetnsLink> NetnsLink::make(const std::string& name, const std::string& host_if, const std::string& ns_if,
                                    const std::string& subnet_prefix, unsigned first_host, bool check_iptables) {
  if (::geteuid() != 0) return invalidArgument("network namespaces need root");
  if (findProgram("ip").empty()) return notFound("'ip' is not installed");
  if (check_iptables && findProgram("iptables").empty()) return notFound("'iptables' is not installed");
  NetnsLink link(name, subnet_prefix + std::to_string(first_host), subnet_prefix + std::to_string(first_host + 1));
  (void)runProgram({"ip", "netns", "del", name});  // a leftover of a killed run
  if (auto s = runProgram({"ip", "netns", "add", name}); !s) {
    link.name_.clear();  // nothing to delete
    return s.error();
  }
  if (auto s = runProgram({"ip", "link", "add", host_if, "type", "veth", "peer", "name", ns_if}); !s) return s.error();
  link.host_if_ = host_if;
  link.ns_if_ = ns_if;
  const std::string ip = findProgram("ip");  // inside `ip netns exec`, PATH may lack /usr/sbin
  std::vector<std::vector<std::string>> steps = {
      {"ip", "link", "set", ns_if, "netns", name},
      {"ip", "addr", "add", link.host_ip_ + "/30", "dev", host_if},
      {"ip", "link", "set", host_if, "up"},
      {"ip", "netns", "exec", name, ip, "addr", "add", link.ns_ip_ + "/30", "dev", ns_if},
      {"ip", "netns", "exec", name, ip, "link", "set", ns_if, "up"},
      {"ip", "netns", "exec", name, ip, "link", "set", "lo", "up"},
      // Every host address (another pair's host side too) is reached through the host side.
      {"ip", "netns", "exec", name, ip, "route", "add", "default", "via", link.host_ip_},
  };
  if (check_iptables) steps.push_back({"ip", "netns", "exec", name, "iptables", "-S"});  // iptables works in here
  for (const auto& step : steps) {
    if (auto s = runProgram(step); !s) return s.error();  // the destructor removes what was made
  }
  return link;
}

NetnsLink::NetnsLink(NetnsLink&& other) noexcept
    : name_(std::move(other.name_)),
      host_ip_(std::move(other.host_ip_)),
      ns_ip_(std::move(other.ns_ip_)),
      host_if_(std::move(other.host_if_)),
      ns_if_(std::move(other.ns_if_)) {
  other.name_.clear();
  other.host_if_.clear();
}

NetnsLink::~NetnsLink() {
  // The host side first: that removes the pair and its address at once, even while processes
  // still run inside (a namespace lives on until its last process exits).
  if (!host_if_.empty()) (void)runProgram({"ip", "link", "del", host_if_});
  if (!name_.empty()) (void)runProgram({"ip", "netns", "del", name_});
}

std::vector<std::string> NetnsLink::prefix() const { return {findProgram("ip"), "netns", "exec", name_}; }

Status NetnsLink::setDropping(bool drop) {
  for (const char* chain : {"INPUT", "OUTPUT"}) {
    if (auto s = runProgram({"ip", "netns", "exec", name_, "iptables", drop ? "-I" : "-D", chain, "-j", "DROP"}); !s) return s;
  }
  return {};
}

Status NetnsLink::setRate(double mbit_per_s) {
  if (!std::isfinite(mbit_per_s) || mbit_per_s <= 0.0 || mbit_per_s > 100000.0) {
    return invalidArgument("a link rate must be above 0 and at most 100000 Mbit/s, not " + std::to_string(mbit_per_s));
  }
  const std::string tc = findProgram("tc");
  if (tc.empty()) return notFound("'tc' is not installed (iproute2): rate limits need it");
  const double bytes_per_s = mbit_per_s * 1e6 / 8.0;
  const auto burst_bytes = static_cast<long long>(std::max(bytes_per_s * 0.010, 2.0 * 1514.0));
  const std::vector<std::string> tbf = {"root", "tbf", "rate", std::to_string(std::llround(mbit_per_s * 1e6)) + "bit",
                                        "burst", std::to_string(burst_bytes), "latency", "50ms"};
  std::vector<std::string> host_side = {"tc", "qdisc", "replace", "dev", host_if_};
  host_side.insert(host_side.end(), tbf.begin(), tbf.end());
  std::vector<std::string> ns_side = {"ip", "netns", "exec", name_, tc, "qdisc", "replace", "dev", ns_if_};
  ns_side.insert(ns_side.end(), tbf.begin(), tbf.end());
  if (auto s = runProgram(host_side); !s) return s;
  return runProgram(ns_side);
}

Status NetnsLink::clearRate() {
  const std::string tc = findProgram("tc");
  if (tc.empty()) return notFound("'tc' is not installed (iproute2): rate limits need it");
  // `tc qdisc del` fails when there is no root qdisc to delete: a plain FIFO put there first makes
  // the delete succeed either way, and the delete restores the device's default (noqueue).
  const std::vector<std::vector<std::string>> steps = {
      {"tc", "qdisc", "replace", "dev", host_if_, "root", "pfifo_fast"},
      {"tc", "qdisc", "del", "dev", host_if_, "root"},
      {"ip", "netns", "exec", name_, tc, "qdisc", "replace", "dev", ns_if_, "root", "pfifo_fast"},
      {"ip", "netns", "exec", name_, tc, "qdisc", "del", "dev", ns_if_, "root"},
  };
  for (const auto& step : steps) {
    if (auto s = runProgram(step); !s) return s;
  }
  return {};
}

}  // namespace fogmap::harness
