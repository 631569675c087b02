// Monitoring without Docker: a real Prometheus (Debian's package) scrapes a cluster started by
// `fogctl up` (edges, the root, a tracker and a HOG camera on the bundled KITTI frames), configured
// as `fogctl compose` configures the deployment, with the repository's alert and recording rules.
// Every query of the Grafana dashboards and every rule must return data; killing an edge must fire
// FogmapSensorMissing. The committed deployment files must be what their generating commands make
// now.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <array>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "common/config/topology.hpp"
#include "common/config/topology_parse.hpp"
#include "common/config/topology_presets.hpp"
#include "common/config/topology_yaml.hpp"
#include "tests/support/shell.hpp"
#include "tests/support/free_ports.hpp"
#include "harness/compose.hpp"
#include "harness/launcher.hpp"

namespace fogmap {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

const fs::path kSource = FOGMAP_SOURCE_DIR;

std::pair<int, std::string> run(const std::string& command) { return test_support::runCommand(command); }

std::string readFile(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

fs::path scratchDir(const std::string& name) {
  const auto dir = fs::temp_directory_path() / ("fogmap-mon-" + std::to_string(::getpid()) + "-" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

bool havePrometheus() { return run("prometheus --version").first == 0 && run("promtool --version").first == 0; }

#define REQUIRE_PROMETHEUS()                                                                              \
  if (!havePrometheus()) {                                                                                \
    GTEST_SKIP() << "SKIPPED: no Prometheus server or promtool here (the Debian package prometheus, "      \
                    "installed by tools/install-deps.sh)";                                                \
  }

std::string urlEncode(const std::string& text) {
  std::string out;
  for (const unsigned char c : text) {
    if (std::isalnum(c) != 0 || c == '-' || c == '_' || c == '.' || c == '~') {
      out += static_cast<char>(c);
    } else {
      char hex[4];
      std::snprintf(hex, sizeof hex, "%%%02X", c);
      out += hex;
    }
  }
  return out;
}

// The query expressions of a Grafana dashboard (JSON strings after "expr"), unescaped.
std::vector<std::string> dashboardQueries(const std::string& json) {
  std::vector<std::string> out;
  static const std::regex expr(R"re("expr"\s*:\s*"((?:[^"\\]|\\.)*)")re");
  for (auto it = std::sregex_iterator(json.begin(), json.end(), expr); it != std::sregex_iterator(); ++it) {
    std::string text;
    const std::string raw = (*it)[1];
    for (std::size_t i = 0; i < raw.size(); ++i) text += (raw[i] == '\\' && i + 1 < raw.size()) ? raw[++i] : raw[i];
    out.push_back(text);
  }
  return out;
}

struct Rule {
  std::string name;  // the record's or the alert's
  std::string expr;
  bool alert = false;
};

std::vector<Rule> rules(const fs::path& file) {
  std::vector<Rule> out;
  const YAML::Node root = YAML::LoadFile(file.string());
  for (const auto& group : root["groups"]) {
    for (const auto& rule : group["rules"]) {
      const bool alert = static_cast<bool>(rule["alert"]);
      out.push_back({rule[alert ? "alert" : "record"].as<std::string>(), rule["expr"].as<std::string>(), alert});
    }
  }
  return out;
}

// An alert's expression compares a quantity with a threshold ("A > B"); with `bool` it returns the
// comparison's 0 or 1 for every series of A, so it has data whether or not the alert fires.
std::string withBool(const std::string& expr) {
  static const std::regex comparison(R"(\s(==|!=|>=|<=|>|<)\s)");
  std::smatch m;
  if (!std::regex_search(expr, m, comparison)) return "";
  return expr.substr(0, static_cast<std::size_t>(m.position(1) + m.length(1))) + " bool" +
         expr.substr(static_cast<std::size_t>(m.position(1) + m.length(1)));
}

// A Prometheus server on 127.0.0.1:port, stopped by the destructor.
class PrometheusServer {
 public:
  PrometheusServer(const fs::path& dir, const std::string& config_text) : port_(test_support::freePorts(1).at(0)) {
    std::ofstream(dir / "prometheus.yml") << config_text;
    pid_ = ::fork();
    if (pid_ == 0) {
      const std::string cfg = "--config.file=" + (dir / "prometheus.yml").string();
      const std::string storage = "--storage.tsdb.path=" + (dir / "tsdb").string();
      const std::string web = "--web.listen-address=127.0.0.1:" + std::to_string(port_);
      std::freopen((dir / "prometheus.log").c_str(), "w", stderr);
      ::execlp("prometheus", "prometheus", cfg.c_str(), storage.c_str(), web.c_str(), static_cast<char*>(nullptr));
      ::_exit(127);
    }
  }
  ~PrometheusServer() {
    if (pid_ > 0) {
      ::kill(pid_, SIGTERM);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  bool started() const { return pid_ > 0; }
  // The answer of /api/v1/query, or the error.
  std::string query(const std::string& promql) const {
    const auto body = harness::httpGet("127.0.0.1", port_, "/api/v1/query?query=" + urlEncode(promql), 2000ms);
    return body.ok() ? *body : "error: " + body.error().message;
  }
  // True when the query succeeded with at least one sample.
  bool hasData(const std::string& promql) const {
    const std::string answer = query(promql);
    return answer.find("\"status\":\"success\"") != std::string::npos && answer.find("\"result\":[{") != std::string::npos;
  }

 private:
  std::uint16_t port_;
  pid_t pid_ = -1;
};

// Polls `condition` every 500 ms until it holds or `timeout` passes.
template <class F>
bool within(std::chrono::seconds timeout, F condition) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < end) {
    if (condition()) return true;
    std::this_thread::sleep_for(500ms);
  }
  return condition();
}

TEST(Monitoring, PromtoolAcceptsTheRulesAndTheirUnitTests) {
  REQUIRE_PROMETHEUS();
  const fs::path dir = kSource / "docker" / "prometheus";
  const auto [check_code, check] = run("promtool check rules " + (dir / "rules.yml").string());
  EXPECT_EQ(check_code, 0) << check;
  const auto [test_code, tested] = run("cd " + dir.string() + " && promtool test rules rules_test.yml");
  EXPECT_EQ(test_code, 0) << tested;
  EXPECT_NE(tested.find("SUCCESS"), std::string::npos) << tested;
  // Every alert and record is exercised by the unit tests.
  const std::string unit_tests = readFile(dir / "rules_test.yml");
  for (const Rule& rule : rules(dir / "rules.yml")) {
    EXPECT_NE(unit_tests.find(rule.name), std::string::npos) << rule.name << " has no unit test in rules_test.yml";
  }
}

// Every committed file that a command generates records the command in its header; running it
// again must give the same file.
TEST(Monitoring, CommittedDeploymentFilesAreWhatTheirCommandsGenerate) {
  const std::string fogctl = (harness::binaryDir() / "fogctl").string();
  std::vector<fs::path> checked;
  for (const char* compose : {"compose.yaml", "compose.tree.yaml"}) {
    std::istringstream lines(readFile(kSource / compose));
    std::string line;
    std::getline(lines, line);
    std::getline(lines, line);  // "#   fogctl compose ..."
    ASSERT_EQ(line.rfind("#   fogctl compose ", 0), 0U) << compose << ": no generating command in its header";
    const auto [code, output] = run("cd " + kSource.string() + " && " + fogctl + line.substr(std::string("#   fogctl").size()) + " --check");
    EXPECT_EQ(code, 0) << compose << ": " << output;
    checked.push_back(compose);
  }
  for (const auto& entry : fs::directory_iterator(kSource / "docker" / "topologies")) {
    const std::string text = readFile(entry.path());
    const std::string prefix = "# fogmap topology, generated by: fogctl ";
    ASSERT_EQ(text.rfind(prefix, 0), 0U) << entry.path();
    const std::string command = text.substr(prefix.size(), text.find('\n') - prefix.size());
    // The command's paths are relative to the topology file (written to stdout: the working directory).
    const auto [code, output] = run("cd " + entry.path().parent_path().string() + " && " + fogctl + " " + command + " 2>/dev/null");
    EXPECT_EQ(code, 0) << entry.path();
    EXPECT_EQ(output, text) << entry.path() << " is not what `fogctl " << command << "` writes";
    // The topology loads, and every node is a service of the compose file made from it.
    const auto topology = loadTopology(entry.path());
    ASSERT_TRUE(topology.ok()) << topology.error().message;
    checked.push_back(entry.path());
  }
  EXPECT_EQ(checked.size(), 4U) << "compose.yaml, compose.tree.yaml and their two topologies";
}

TEST(Monitoring, ComposeRefusesFilesOutsideTheMountedDirectoryAndReservedNames) {
  TopologyConfig t = makeStarTopology(2, kSource / "data" / "kitti_raw_seq_a", 41000);
  harness::ComposeOptions options;
  options.topology_file = kSource / "docker" / "topologies" / "star-4.yaml";
  options.project_dir = kSource;
  options.prometheus_config = "docker/prometheus/prometheus.yml";
  const auto ok = harness::composeFile(t, options);
  ASSERT_TRUE(ok.ok()) << ok.error().message;
  for (const NodeConfig& node : t.nodes) {
    EXPECT_NE(ok->find("  " + node.name + ":\n"), std::string::npos) << node.name;
    EXPECT_NE(ok->find(std::string("command: [") + serviceName(node.role) + ", --topology, /fogmap/docker/topologies/star-4.yaml, --node, " +
                       node.name + "]"),
              std::string::npos)
        << *ok;
  }
  t.nodes[1].sensor->source = "/somewhere/else";
  const auto outside = harness::composeFile(t, options);
  ASSERT_FALSE(outside.ok());
  EXPECT_NE(outside.error().message.find("edge-1's sensor source /somewhere/else lies outside"), std::string::npos)
      << outside.error().message;
  t = makeStarTopology(2, kSource / "data" / "kitti_raw_seq_a", 41000);
  t.nodes[0].name = "prometheus";
  t.nodes[1].parent = t.nodes[2].parent = "prometheus";
  const auto reserved = harness::composeFile(t, options);
  ASSERT_FALSE(reserved.ok());
  EXPECT_NE(reserved.error().message.find("node 'prometheus' has the name of the deployment's prometheus service"),
            std::string::npos)
      << reserved.error().message;
}

TEST(Monitoring, EveryDashboardQueryAndRuleHasDataFromARealPrometheusAndAKilledEdgeFiresTheAlert) {
  REQUIRE_PROMETHEUS();
  const fs::path dir = scratchDir("cluster");
  const std::string fogctl = (harness::binaryDir() / "fogctl").string();
  // The star the deployment runs, smaller: 3 edges, the root, the tracker and a camera node running
  // HOG on the bundled KITTI frames (at 2 Hz: the test machine's cores go to the LiDAR pipeline).
  const fs::path topology_file = dir / "monitoring.yaml";
  const auto [made_code, made] =
      run(fogctl + " topology star --edges 3 --source " + (kSource / "data" / "kitti_raw_seq_a").string() +
          " --tracker --cameras " + (kSource / "data" / "kitti_raw_seq_a" / "image_02").string() +
          " --camera-rate-hz 2 --out " + topology_file.string());
  ASSERT_EQ(made_code, 0) << made;
  auto loaded = loadTopology(topology_file);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  TopologyConfig t = *loaded;
  ASSERT_EQ(t.nodes.size(), 6U) << "sink, 3 edges, tracker, camera";
  test_support::useFreePorts(t);
  t.name = "monitoring";
  t.deadline_ms = 300.0;  // a loaded test machine must not turn every epoch into a partial one
  std::ofstream(topology_file) << toYaml(t);
  const fs::path state = dir / "state";
  const auto [up_code, up] = run(fogctl + " up " + topology_file.string() + " --detach --state " + state.string());
  ASSERT_EQ(up_code, 0) << up;
  struct Down {
    std::string command;
    ~Down() { std::system((command + " > /dev/null 2>&1").c_str()); }
  } down{fogctl + " down --state " + state.string()};

  // Each service's exposition passes promtool's lint.
  for (const NodeConfig& n : t.nodes) {
    const auto text = harness::httpGet(n.host, n.metrics_port, "/metrics", 2000ms);
    ASSERT_TRUE(text.ok()) << n.name;
    std::ofstream(dir / (n.name + ".prom")) << *text;
    const auto [code, problems] = run("promtool check metrics < " + (dir / (n.name + ".prom")).string());
    EXPECT_EQ(code, 0) << n.name << ": " << problems;
    EXPECT_EQ(problems, "") << n.name;
  }

  harness::PrometheusOptions scrape;
  scrape.rule_files = {(kSource / "docker" / "prometheus" / "rules.yml").string()};
  scrape.scrape_interval = "1s";
  scrape.evaluation_interval = "1s";
  scrape.command = "monitoring_test";
  const std::string config = harness::prometheusConfig(t, scrape);
  std::ofstream(dir / "check.yml") << config;
  const auto [config_code, config_check] = run("promtool check config " + (dir / "check.yml").string());
  EXPECT_EQ(config_code, 0) << config_check;

  const PrometheusServer prometheus(dir, config);
  ASSERT_TRUE(prometheus.started());
  const std::string all_up = "count(up{job=\"fogmap\"} == 1) == " + std::to_string(t.nodes.size());
  ASSERT_TRUE(within(60s, [&] { return prometheus.hasData(all_up); })) << prometheus.query("up");

  std::vector<std::pair<std::string, std::string>> queries;  // (what, PromQL)
  for (const auto& dashboard : fs::directory_iterator(kSource / "docker" / "grafana" / "dashboards")) {
    for (const std::string& q : dashboardQueries(readFile(dashboard.path()))) {
      queries.emplace_back("dashboard " + dashboard.path().filename().string(),
                           std::regex_replace(q, std::regex(R"(\$__rate_interval)"), "15s"));
    }
  }
  EXPECT_GE(queries.size(), 28U) << "fogmap.json and tracking.json";
  for (const Rule& rule : rules(kSource / "docker" / "prometheus" / "rules.yml")) {
    if (!rule.alert) {
      queries.emplace_back("record " + rule.name, rule.name);  // evaluated by Prometheus itself
      continue;
    }
    const std::string with_bool = withBool(rule.expr);
    EXPECT_FALSE(with_bool.empty()) << rule.name << ": not of the form A <comparison> B: " << rule.expr;
    queries.emplace_back("alert " + rule.name, with_bool);
  }
  std::vector<std::string> without_data;
  within(90s, [&] {
    without_data.clear();
    for (const auto& [what, q] : queries) {
      if (!prometheus.hasData(q)) without_data.push_back(what + ": " + q);
    }
    return without_data.empty();
  });
  for (const std::string& q : without_data) ADD_FAILURE() << "no data for " << q << "\n  " << prometheus.query(q.substr(q.find(": ") + 2));
  EXPECT_TRUE(prometheus.hasData("fogmap_global_objects > 0")) << prometheus.query("fogmap_global_objects");
  EXPECT_TRUE(within(60s, [&] { return prometheus.hasData("sum(fogmap_tracks{state=\"confirmed\"}) > 0"); }))
      << prometheus.query("fogmap_tracks");
  EXPECT_TRUE(prometheus.hasData("fogmap_camera_frames_total{outcome=\"detected\"} > 0")) << prometheus.query("fogmap_camera_frames_total");
  EXPECT_FALSE(prometheus.hasData("ALERTS{alertname=\"FogmapCameraStale\"}")) << "the camera runs: " << prometheus.query("fogmap_camera_staleness_seconds");
  EXPECT_TRUE(prometheus.hasData("sum(fogmap_sensor_missing) == 0")) << prometheus.query("fogmap_sensor_missing");
  const std::string firing = "ALERTS{alertname=\"FogmapSensorMissing\",alertstate=\"firing\",sensor=\"edge-2\"}";
  EXPECT_FALSE(prometheus.hasData(firing)) << "fired while edge-2 was up";

  // kill -9 of edge-2: the root marks it missing and, after the rule's 15 s, the alert fires.
  pid_t edge = -1;
  std::istringstream pids(readFile(state / "pids"));
  for (std::string line; std::getline(pids, line);) {
    long pid = 0;
    char name[128] = {};
    if (std::sscanf(line.c_str(), "%ld %127s", &pid, name) == 2 && std::string(name) == "edge-2") edge = static_cast<pid_t>(pid);
  }
  ASSERT_GT(edge, 0) << readFile(state / "pids");
  ASSERT_EQ(::kill(edge, SIGKILL), 0);
  const auto killed = std::chrono::steady_clock::now();
  EXPECT_TRUE(within(20s, [&] { return prometheus.hasData("fogmap_sensor_missing{sensor=\"edge-2\"} == 1"); }))
      << prometheus.query("fogmap_sensor_missing");
  EXPECT_TRUE(within(60s, [&] { return prometheus.hasData(firing); })) << prometheus.query("ALERTS");
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - killed).count();
  EXPECT_GE(seconds, 15.0) << "the alert waits for its `for` of 15 s";
  EXPECT_FALSE(prometheus.hasData("ALERTS{alertname=\"FogmapSensorMissing\",sensor!=\"edge-2\"}")) << prometheus.query("ALERTS");
  std::printf("%zu dashboard queries and rules had data; FogmapSensorMissing fired %.1f s after kill -9 of edge-2\n",
              queries.size(), seconds);
}

}  // namespace
}  // namespace fogmap
