#include "tools/fogctl/args.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <thread>

#include "common/certs/certs.hpp"
#include "common/classify/object_classifier.hpp"
#include "common/config/topology_parse.hpp"
#include "common/io/cloud_io.hpp"
#include "common/perception/preprocess.hpp"
#include "harness/launcher.hpp"
#include "services/common/grpc_options.hpp"

namespace fogmap::cli {

Expected<Args> Args::parse(int argc, char** argv, int first, const std::set<std::string>& valued,
                           const std::set<std::string>& switches) {
  Args args;
  for (int i = first; i < argc; ++i) {
    const std::string token = argv[i];
    if (token.rfind("--", 0) != 0) {
      args.positional_.push_back(token);
      continue;
    }
    const std::string name = token.substr(2);
    if (switches.count(name) > 0) {
      args.values_.insert_or_assign(name, std::string("1"));
    } else if (valued.count(name) > 0) {
      if (i + 1 >= argc) return invalidArgument("flag --" + name + " needs a value");
      args.values_[name] = argv[++i];
    } else {
      return invalidArgument("unknown flag --" + name);
    }
  }
  return args;
}

std::string Args::get(const std::string& name, const std::string& fallback) const {
  const auto it = values_.find(name);
  return it == values_.end() ? fallback : it->second;
}

Expected<double> Args::getDouble(const std::string& name, double fallback) const {
  const auto it = values_.find(name);
  if (it == values_.end()) return fallback;
  char* end = nullptr;
  const double v = std::strtod(it->second.c_str(), &end);
  if (end == it->second.c_str() || *end != '\0' || !std::isfinite(v)) {
    return invalidArgument("--" + name + " expects a number, got '" + it->second + "'");
  }
  return v;
}

Expected<long> Args::getInt(const std::string& name, long fallback) const {
  const auto it = values_.find(name);
  if (it == values_.end()) return fallback;
  char* end = nullptr;
  const long v = std::strtol(it->second.c_str(), &end, 10);
  if (end == it->second.c_str() || *end != '\0') {
    return invalidArgument("--" + name + " expects an integer, got '" + it->second + "'");
  }
  return v;
}

int fail(const Error& error, const std::string& who) {
  std::cerr << who << ": " << error.message << "\n";
  return error.code == ErrorCode::kInvalidArgument ? 2 : 1;
}

Expected<std::filesystem::path> absoluteDir(const std::filesystem::path& dir) {
  std::error_code ec;
  const auto absolute = std::filesystem::absolute(dir, ec);
  if (ec || dir.empty()) return invalidArgument("cannot use '" + dir.string() + "' as a directory: " + (ec ? ec.message() : "it is empty"));
  const auto canonical = std::filesystem::weakly_canonical(absolute, ec);
  return ec ? absolute.lexically_normal() : canonical;
}

Expected<std::filesystem::path> stateDir(const Args& args, const std::filesystem::path& topology_file, const TopologyConfig& t) {
  if (args.has("state")) return absoluteDir(args.get("state"));
  std::error_code ec;
  const auto file = std::filesystem::absolute(topology_file, ec);
  if (ec) return invalidArgument("cannot resolve " + topology_file.string() + ": " + ec.message());
  return absoluteDir(file.parent_path() / ".fogmap" / t.name);
}

namespace {

// The client identity fogctl uses by default when the topology has a tls section.
constexpr const char* kDefaultIdentity = "operator";

}  // namespace

Expected<RootConnection> rootConnection(const Args& args, const std::string& usage, Role server) {
  std::optional<TopologyConfig> topology;
  if (!args.has("target") || args.has("identity")) {
    if (args.positional().size() != 1) {
      return invalidArgument(args.has("identity") ? "--identity needs the topology file (its tls section says where the "
                                                    "certificates are); with --target give --cert, --key and --ca"
                                                  : "usage: " + usage);
    }
    auto loaded = loadTopology(args.positional()[0]);
    if (!loaded) return loaded.error();
    topology = std::move(*loaded);
  }
  RootConnection connection;
  if (args.has("target")) {
    connection.target = args.get("target");
  } else {
    // The root, or the first tracker.
    const NodeConfig* node = topology->root();
    if (server == Role::kTracker) {
      const auto tracker = std::find_if(topology->nodes.begin(), topology->nodes.end(),
                                        [](const NodeConfig& n) { return n.role == Role::kTracker; });
      if (tracker == topology->nodes.end()) return invalidArgument(args.positional()[0] + " has no tracker");
      node = &*tracker;
    }
    connection.target = endpoint(node->host, node->port);
  }
  const auto now = std::chrono::system_clock::now();
  const bool explicit_files = args.has("cert") || args.has("key") || args.has("ca");
  if (explicit_files) {
    if (args.has("identity")) return invalidArgument("give either --identity or --cert, --key and --ca, not both");
    for (const char* flag : {"cert", "key", "ca"}) {
      if (!args.has(flag)) return invalidArgument(std::string("--cert, --key and --ca go together: --") + flag + " is missing");
    }
    auto tls = loadTls(TlsIdentity{args.get("ca"), args.get("cert"), args.get("key")}, now);
    if (!tls) return Error{tls.error().code, "tls: " + tls.error().message};
    connection.credentials = channelCredentials(*tls);
    return connection;
  }
  if (!topology || !topology->tls) {
    if (args.has("identity")) return invalidArgument("--identity: " + args.positional()[0] + " has no tls section");
    connection.credentials = channelCredentials(std::nullopt);
    return connection;
  }
  const std::string identity = args.get("identity", kDefaultIdentity);
  const auto files = topology->tlsIdentity(identity);
  std::error_code ec;
  if (!args.has("identity") && !std::filesystem::exists(files->cert, ec)) {
    return invalidArgument(args.positional()[0] + " uses TLS, and fogctl needs a client certificate: give --identity NAME "
                           "(NAME.crt and NAME.key in " + topology->tls->cert_dir.string() + ") or --cert, --key and "
                           "--ca; the default identity '" + identity + "' has no certificate (" + files->cert.string() +
                           "; fogctl certs makes one)");
  }
  auto tls = loadTls(*topology, identity, now);
  if (!tls) return Error{tls.error().code, "tls: identity '" + identity + "': " + tls.error().message};
  connection.credentials = channelCredentials(*tls);
  return connection;
}

Expected<ClusteringParams> clusteringParams(const Args& args) {
  ClusteringParams p;
  const auto eps = args.getDouble("eps", p.eps_m);
  if (!eps) return eps.error();
  const auto min_points = args.getInt("min-points", static_cast<long>(p.min_points));
  if (!min_points) return min_points.error();
  const auto threads = args.getInt("threads", static_cast<long>(std::max(1U, std::thread::hardware_concurrency())));
  if (!threads) return threads.error();
  if (*threads < 1 || *threads > 256) return invalidArgument("--threads must be between 1 and 256");
  p.eps_m = *eps;
  // A negative count would wrap to a huge size_t; 0 gets validateClusteringParams' own message.
  p.min_points = static_cast<std::size_t>(std::max(0L, *min_points));
  p.threads = static_cast<std::size_t>(*threads);
  if (const Status valid = validateClusteringParams(p); !valid) {
    return invalidArgument("--eps/--min-points: " + valid.error().message);
  }
  return p;
}

Expected<Cloud> loadScan(const Args& args, bool keep_non_finite) {
  if (!args.has("input")) return invalidArgument("--input SCAN is required");
  const auto max_bytes = args.getInt("max-scan-bytes", static_cast<long>(kDefaultMaxScanBytes));
  if (!max_bytes || *max_bytes < 1) return invalidArgument("--max-scan-bytes expects a positive number of bytes");
  const ReadLimits limits{static_cast<std::uintmax_t>(*max_bytes), keep_non_finite};
  const std::filesystem::path input = args.get("input");
  auto loaded = readCloud(input, limits);
  if (!loaded) {
    std::error_code ec;
    const auto size = std::filesystem::file_size(input, ec);
    if (!ec && size > limits.max_bytes) {
      return Error{loaded.error().code, loaded.error().message + "; raise the bound with --max-scan-bytes"};
    }
    return loaded.error();
  }
  if (loaded->dropped_non_finite > 0) {
    std::cerr << "fogctl: dropped " << loaded->dropped_non_finite << " non-finite points\n";
  }
  if (loaded->kept_non_finite > 0) {
    std::cerr << "fogctl: " << loaded->kept_non_finite << " non-finite points, labelled noise\n";
  }
  if (!args.has("remove-ground")) return std::move(loaded->points);
  auto ground = removeGround(loaded->points, GroundParams{});
  if (!ground) return ground.error();
  return std::move(ground->non_ground);
}

Expected<sim::SceneMapping> sceneMapping(const Args& args, const sim::SceneMapping& defaults) {
  sim::SceneMapping mapping = defaults;
  if (args.has("clustering")) {
    const auto mode = parseClusteringMode(args.get("clustering"));
    if (!mode) return invalidArgument("--clustering " + mode.error().message);
    mapping.clustering = *mode;
  }
  if (args.get("fragment-min-points") == "off") {
    mapping.fragment_min_points.reset();
  } else if (args.has("fragment-min-points")) {
    const auto n = args.getInt("fragment-min-points", 0);
    if (!n || *n < 1 || *n > 1000) return invalidArgument("--fragment-min-points must be off or in [1, 1000]");
    mapping.fragment_min_points = static_cast<std::size_t>(*n);
  }
  if (args.get("alpha-max") == "off") {
    mapping.alpha_max = 0.0;
  } else if (args.has("alpha-max")) {
    const auto a = args.getDouble("alpha-max", 0.0);
    if (!a || !(*a > 0.0 && *a < 10.0)) return invalidArgument("--alpha-max must be off or in (0, 10)");
    mapping.alpha_max = *a;
  }
  if (args.has("objects")) {
    const std::string objects = args.get("objects");
    if (objects != "none" && objects != "boxes" && objects != "classes") {
      return invalidArgument("--objects must be none, boxes or classes, got '" + objects + "'");
    }
    mapping.objects.boxes = objects != "none";
    mapping.objects.classifier.reset();
    if (objects == "classes") {
      const auto bundled = bundledClassifierModel();
      mapping.objects.classifier = std::filesystem::absolute(args.get("classifier", bundled ? bundled->string() : kDefaultClassifierModel));
    }
  }
  if (args.has("classifier")) {
    if (!mapping.objects.classifier) return invalidArgument("--classifier goes with --objects classes");
    mapping.objects.classifier = std::filesystem::absolute(args.get("classifier"));
  }
  return mapping;
}

std::optional<std::filesystem::path> bundledClassifierModel() {
  for (const auto& candidate : {harness::binaryDir() / ".." / ".." / kDefaultClassifierModel, std::filesystem::path(kDefaultClassifierModel)}) {
    std::error_code error;
    if (std::filesystem::is_regular_file(candidate, error)) return std::filesystem::absolute(candidate).lexically_normal();
  }
  return std::nullopt;
}

Expected<std::shared_ptr<const ObjectClassifier>> classifierFlag(const Args& args) {
  const std::string model = args.get("classifier", kDefaultClassifierModel);
  if (!args.has("classifier") && !std::filesystem::exists(model)) return std::shared_ptr<const ObjectClassifier>();
  auto loaded = ObjectClassifier::load(model);
  if (!loaded) return loaded.error();
  return std::shared_ptr<const ObjectClassifier>(std::make_shared<ObjectClassifier>(std::move(*loaded)));
}

}  // namespace fogmap::cli
