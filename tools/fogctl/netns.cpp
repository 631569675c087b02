#include "tools/fogctl/netns.hpp"

#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <sstream>

namespace fogmap::cli {

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
  const pid_t pid = ::fork();
  if (pid < 0) return ioError("fork failed for: " + line);
  if (pid == 0) {
    const int null = ::open("/dev/null", O_WRONLY);
    if (null >= 0) {
      ::dup2(null, STDOUT_FILENO);
      ::dup2(null, STDERR_FILENO);
    }
    ::execv(program.c_str(), args.data());
    ::_exit(127);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) return ioError("command failed: " + line);
  return {};
}

Expected<NetnsLink> NetnsLink::create(unsigned tag) {
  if (::geteuid() != 0) return invalidArgument("network namespaces need root");
  for (const char* tool : {"ip", "iptables"}) {
    if (findProgram(tool).empty()) return notFound(std::string("'") + tool + "' is not installed");
  }
  const unsigned n = tag % 250U;
  const std::string name = "fogmap-" + std::to_string(tag);
  const std::string host_if = "fmh" + std::to_string(tag % 100000U);
  const std::string ns_if = "fmn" + std::to_string(tag % 100000U);
  const std::string subnet = "10.213." + std::to_string(n) + ".";
  NetnsLink link(name, subnet + "1", subnet + "2");
  (void)runProgram({"ip", "netns", "del", name});  // a leftover of a killed run
  if (auto s = runProgram({"ip", "netns", "add", name}); !s) {
    link.name_.clear();  // nothing to delete
    return s.error();
  }
  const std::vector<std::vector<std::string>> steps = {
      {"ip", "link", "add", host_if, "type", "veth", "peer", "name", ns_if},
      {"ip", "link", "set", ns_if, "netns", name},
      {"ip", "addr", "add", link.host_ip_ + "/30", "dev", host_if},
      {"ip", "link", "set", host_if, "up"},
      {"ip", "netns", "exec", name, "ip", "addr", "add", link.ns_ip_ + "/30", "dev", ns_if},
      {"ip", "netns", "exec", name, "ip", "link", "set", ns_if, "up"},
      {"ip", "netns", "exec", name, "ip", "link", "set", "lo", "up"},
      {"ip", "netns", "exec", name, "iptables", "-S"},  // iptables works in here
  };
  for (const auto& step : steps) {
    if (auto s = runProgram(step); !s) return s.error();  // the destructor removes what was made
  }
  return link;
}

NetnsLink::NetnsLink(NetnsLink&& other) noexcept
    : name_(std::move(other.name_)), host_ip_(std::move(other.host_ip_)), ns_ip_(std::move(other.ns_ip_)) {
  other.name_.clear();
}

NetnsLink::~NetnsLink() {
  if (!name_.empty()) (void)runProgram({"ip", "netns", "del", name_});  // takes the veth pair with it
}

std::vector<std::string> NetnsLink::prefix() const { return {findProgram("ip"), "netns", "exec", name_}; }

Status NetnsLink::setDropping(bool drop) {
  for (const char* chain : {"INPUT", "OUTPUT"}) {
    if (auto s = runProgram({"ip", "netns", "exec", name_, "iptables", drop ? "-I" : "-D", chain, "-j", "DROP"}); !s) return s;
  }
  return {};
}

}  // namespace fogmap::cli
