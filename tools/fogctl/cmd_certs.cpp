// fogctl certs: a CA and a certificate for every node of a topology and every named client, for
// the topology's tls section.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "common/certs/certs.hpp"
#include "common/config/topology.hpp"
#include "common/config/topology_parse.hpp"
#include "harness/compose.hpp"
#include "tools/fogctl/args.hpp"
#include "tools/fogctl/commands.hpp"

namespace fogmap::cli {
namespace {

constexpr long kMaxDays = 36500;
// Issued a little in the past, so that a peer whose clock is slightly behind accepts them at once.
constexpr std::chrono::minutes kBackdate{5};

// Writes `text` to `path` with permissions `mode` (also when the file existed with others).
Status writeFile(const std::filesystem::path& path, const std::string& text, mode_t mode) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, mode);
  if (fd < 0) return ioError("cannot write " + path.string() + ": " + std::strerror(errno));
  bool ok = ::fchmod(fd, mode) == 0;
  std::size_t done = 0;
  while (ok && done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    ok = n > 0;
    if (ok) done += static_cast<std::size_t>(n);
  }
  const int saved = errno;
  ok = (::close(fd) == 0) && ok;
  if (!ok) return ioError("cannot write " + path.string() + ": " + std::strerror(saved));
  return {};
}

// `key_owner`: the uid that owns the private key (the user a container runs the service as), or
// -1 for the invoking user.
Status writePair(const std::filesystem::path& dir, const std::string& name, const PemPair& pair, long key_owner = -1) {
  if (const Status s = writeFile(dir / (name + ".crt"), pair.cert, 0644); !s) return s;
  const auto key = dir / (name + ".key");
  if (const Status s = writeFile(key, pair.key, 0600); !s) return s;  // the private key: its owner only
  if (key_owner >= 0 && ::chown(key.c_str(), static_cast<uid_t>(key_owner), static_cast<gid_t>(-1)) != 0) {
    return ioError("cannot give " + key.string() + " to uid " + std::to_string(key_owner) + ": " + std::strerror(errno) +
                   " (--owner needs root)");
  }
  return {};
}

// "a,b,c" -> {a, b, c}, empty items skipped.
std::vector<std::string> splitList(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

std::string dateOf(std::chrono::system_clock::time_point t) {
  const std::time_t seconds = std::chrono::system_clock::to_time_t(t);
  std::tm utc{};
  gmtime_r(&seconds, &utc);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%d %H:%M UTC", &utc);
  return text;
}

int runCerts(int argc, char** argv) {
  const std::string usage =
      "usage: fogctl certs TOPOLOGY.yaml --out DIR [--days 365] [--clients operator,...] [--owner UID] [--force]";
  const auto args = Args::parse(argc, argv, 2, {"out", "days", "clients", "owner"}, {"force"});
  if (!args) return fail(args.error(), "fogctl certs");
  if (args->positional().size() != 1 || !args->has("out")) return fail(invalidArgument(usage), "fogctl certs");
  const auto topology = loadTopology(args->positional()[0]);
  if (!topology) return fail(topology.error(), "fogctl certs");
  const auto days = args->getInt("days", 365);
  if (!days) return fail(days.error(), "fogctl certs");
  if (*days < 1 || *days > kMaxDays) return fail(invalidArgument("--days must be in [1, " + std::to_string(kMaxDays) + "]"), "fogctl certs");

  const auto owner = args->getInt("owner", -1);
  if (!owner) return fail(owner.error(), "fogctl certs");
  if (args->has("owner") && (*owner < 0 || *owner > 65534)) return fail(invalidArgument("--owner must be a uid in [0, 65534]"), "fogctl certs");

  std::vector<std::string> clients;
  if (args->has("clients")) {
    clients = splitList(args->get("clients"));
  } else {
    clients.push_back("operator");
    clients.push_back(harness::kViewIdentity);
    if (topology->tls) clients.insert(clients.end(), topology->tls->geofence_clients.begin(), topology->tls->geofence_clients.end());
  }
  for (const auto& client : clients) {
    if (!isCertificateName(client)) {
      return fail(invalidArgument("--clients: '" + client + "' is not a certificate name (letters, digits, '.', '_', '-'; not 'ca')"), "fogctl certs");
    }
    if (topology->find(client) != nullptr) return fail(invalidArgument("--clients: '" + client + "' is a node of the topology"), "fogctl certs");
  }
  std::sort(clients.begin(), clients.end());
  clients.erase(std::unique(clients.begin(), clients.end()), clients.end());
  for (const auto& node : topology->nodes) {
    if (!isCertificateName(node.name)) {
      return fail(invalidArgument("node '" + node.name + "': its name is not a certificate name (letters, digits, '.', '_', "
                                  "'-'; not 'ca')"), "fogctl certs");
    }
  }

  const std::filesystem::path out = args->get("out");
  std::error_code ec;
  std::filesystem::create_directories(out, ec);
  if (ec) return fail(ioError("cannot create " + out.string() + ": " + ec.message()), "fogctl certs");
  if (!args->has("force") && (std::filesystem::exists(out / "ca.crt", ec) || std::filesystem::exists(out / "ca.key", ec))) {
    return fail(invalidArgument(out.string() + " already holds a CA; --force replaces it (certificates it issued are then "
                                "no longer trusted)"), "fogctl certs");
  }

  const auto now = std::chrono::system_clock::now();
  const auto not_before = now - kBackdate;
  const auto not_after = now + std::chrono::hours(24) * *days;
  const auto ca = makeCertificateAuthority("fogmap CA " + topology->name, not_before, not_after);
  if (!ca) return fail(ca.error(), "fogctl certs");
  if (const Status s = writePair(out, "ca", *ca); !s) return fail(s.error(), "fogctl certs");
  for (const auto& node : topology->nodes) {
    // The DNS name is the node's name; the IP address is where its peers connect to it.
    const auto pair = issueCertificate(*ca, {node.name, {node.name}, {node.host}, not_before, not_after});
    if (!pair) return fail(pair.error(), "fogctl certs");
    if (const Status s = writePair(out, node.name, *pair, *owner); !s) return fail(s.error(), "fogctl certs");
  }
  for (const auto& client : clients) {
    const auto pair = issueCertificate(*ca, {client, {client}, {}, not_before, not_after});
    if (!pair) return fail(pair.error(), "fogctl certs");
    // The deployment's live view runs in a container as --owner, as the nodes do.
    const long client_owner = client == harness::kViewIdentity ? *owner : -1;
    if (const Status s = writePair(out, client, *pair, client_owner); !s) return fail(s.error(), "fogctl certs");
  }
  std::string client_list;
  for (const auto& client : clients) client_list += (client_list.empty() ? "" : ", ") + client;
  std::printf("wrote a CA and %zu certificates (%zu nodes; clients: %s) to %s, valid until %s\n",
              topology->nodes.size() + clients.size(), topology->nodes.size(), client_list.empty() ? "none" : client_list.c_str(),
              out.c_str(), dateOf(not_after).c_str());
  // Relative paths in a topology are taken from its own directory.
  // Only what to print is left: a path that cannot be resolved must not throw now that all is written.
  const auto topology_dir = std::filesystem::absolute(args->positional()[0], ec).parent_path();
  const auto ca_path = std::filesystem::absolute(out / "ca.crt", ec).lexically_normal();
  const auto relative = ca_path.lexically_relative(topology_dir);
  const bool below = !relative.empty() && *relative.begin() != "..";
  if (!topology->tls) {
    std::printf("TLS is on once the topology says: tls: {ca: %s, geofence_clients: [operator]}\n",
                (below ? relative : ca_path).c_str());
  } else if (std::filesystem::absolute(topology->tls->ca, ec).lexically_normal() != ca_path) {
    std::printf("note: the topology's tls.ca is %s, not this CA\n", topology->tls->ca.c_str());
  }
  return 0;
}

}  // namespace

Command certsCommand() {
  return {"certs",
          "TOPOLOGY.yaml --out DIR [--days 365] [--clients operator,...]   a CA and certificates for mutual TLS",
          "usage: fogctl certs TOPOLOGY.yaml --out DIR [--days 365] [--clients operator,...] [--owner UID] [--force]\n"
          "Makes a CA (DIR/ca.crt, ca.key) and a certificate for every node of the topology and every client\n"
          "named (DIR/NAME.crt, NAME.key; keys readable by their owner only), EC P-256, signed by the CA.\n"
          "A certificate's common name is its holder's identity; a node's also names its host (IP\n"
          "subjectAltName), so its peers verify HOST:PORT. Point the topology at them: tls: {ca: DIR/ca.crt}.\n"
          "  --days N       valid from now for N days (default 365)\n"
          "  --clients A,B  client identities besides the nodes, for fogctl --identity\n"
          "                 (default: operator, view (the compose deployment's live view) and the\n"
          "                 topology's tls.geofence_clients)\n"
          "  --owner UID    give the nodes' and the view's private keys to UID (as root): the user the services run as,\n"
          "                 10001 in the fogmap image (fogctl compose)\n"
          "  --force        replace a CA already in DIR (what it issued is no longer trusted)\n",
          runCerts};
}

}  // namespace fogmap::cli
