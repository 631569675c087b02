// The live view in a real browser: headless Chromium loads `fogctl view`'s page against a cluster
// started by `fogctl up` on a moving scene, and the test reads the page's own state (what it drew):
// the objects and tracks appear and move, the root's loss shows and the page recovers by itself
// when the root is back, and three browsers are served at once. Skipped, with the reason, where
// Chromium cannot start (tools/install-deps.sh installs it).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/config/topology_parse.hpp"
#include "common/config/topology_yaml.hpp"
#include "harness/cluster_run.hpp"
#include "harness/launcher.hpp"
#include "tests/support/free_ports.hpp"
#include "tests/support/scratch_dir.hpp"
#include "tests/support/shell.hpp"
#include "tests/support/source_dir.hpp"

namespace fogmap {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using test_support::runCommand;

const std::string kDriver = (test_support::kSourceDir / "tests" / "view" / "headless_page.py").string();

json readJson(const fs::path& path) { return json::parse(test_support::readFile(path), nullptr, false); }

// Stops what the test started in the background, however the test ends.
struct Cleanup {
  std::vector<std::string> commands;
  ~Cleanup() {
    for (const auto& c : commands) runCommand(c);
  }
};

TEST(ViewBrowser, ThePageShowsTheSceneMovingLosesTheRootAndRecoversAndServesSeveralBrowsers) {
  test_support::ScratchDir dir("view-browser");
  const std::string fogctl = (harness::binaryDir() / "fogctl").string();
  // A probe: the driver exits 77 when Chromium is missing or cannot start here.
  const auto [probe_code, probe] = runCommand("python3 " + kDriver + " about:blank");
  if (probe_code == 77) GTEST_SKIP() << probe;
  ASSERT_EQ(probe_code, 0) << probe;

  // Three people and a car walked and driven past two LiDARs and a camera, as `fogctl demo --scene` runs them.
  const fs::path scene = dir.path() / "scene.yaml";
  const fs::path topology_file = dir.path() / "view.yaml";
  auto made = runCommand(fogctl + " scene moving --people 3 --vehicles 1 --lidars 2 --cameras 1 --seed 5 --out " + scene.string());
  ASSERT_EQ(made.first, 0) << made.second;
  made = runCommand(fogctl + " topology --scene " + scene.string() + " --tracker --objects boxes --out " + topology_file.string());
  ASSERT_EQ(made.first, 0) << made.second;
  auto loaded = loadTopology(topology_file);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  TopologyConfig topology = *loaded;
  test_support::useFreePorts(topology);
  topology.deadline_ms = 300.0;  // a loaded machine must not turn every epoch into a partial one
  std::ofstream(topology_file) << toYaml(topology);
  const fs::path state = dir.path() / "state";
  Cleanup cleanup;
  const auto up = runCommand(fogctl + " up " + topology_file.string() + " --detach --state " + state.string());
  ASSERT_EQ(up.first, 0) << up.second;
  cleanup.commands.push_back(fogctl + " down --state " + state.string());

  // The root's command line, to start it again after the test kills it.
  const NodeConfig& root = *topology.root();
  const auto plan = runCommand(fogctl + " up " + topology_file.string() + " --dry-run --state " + (dir.path() / "plan").string());
  ASSERT_EQ(plan.first, 0) << plan.second;
  const std::string marker = "would start " + root.name + " (aggregator): ";
  const auto at = plan.second.find(marker);
  ASSERT_NE(at, std::string::npos) << plan.second;
  const std::string root_command = plan.second.substr(at + marker.size(), plan.second.find('\n', at) - at - marker.size());
  const fs::path kill_root = dir.path() / "kill-root.sh";
  const fs::path start_root = dir.path() / "start-root.sh";
  std::ofstream(kill_root) << "pkill -KILL -f -- '--topology " << topology_file.string() << " --node " << root.name << "$'\n";
  std::ofstream(start_root) << root_command << " > " << (dir.path() / "root-again.log").string() << " 2>&1 &\n";
  cleanup.commands.push_back("sh " + kill_root.string());
  // The root's own metrics, saved as metrics-NAME.txt: its publication with one page and with ten.
  const fs::path scrape = dir.path() / "scrape.sh";
  std::ofstream(scrape) << "python3 -c 'import urllib.request,sys; sys.stdout.write(urllib.request.urlopen(\"http://"
                        << root.host << ":" << root.metrics_port << "/metrics\", timeout=5).read().decode())' > "
                        << dir.path().string() << "/metrics-$1.txt\n";

  const auto port = test_support::freePorts(1).at(0);
  const fs::path view_log = dir.path() / "view.log";
  const auto started = runCommand(fogctl + " view " + topology_file.string() + " --port " + std::to_string(port) +
                                  " --geofences 'middle=-6,-6,0,6,6,3' > " + view_log.string() + " 2>&1 & echo $!");
  ASSERT_EQ(started.first, 0) << started.second;
  cleanup.commands.insert(cleanup.commands.begin(), "kill " + started.second);
  const std::string url = "http://127.0.0.1:" + std::to_string(port) + "/";

  const fs::path s1 = dir.path() / "s1.json", s2 = dir.path() / "s2.json", s2b = dir.path() / "s2b.json";
  const fs::path s3 = dir.path() / "s3.json";
  const fs::path s4 = dir.path() / "s4.json", pages = dir.path() / "pages.json";
  std::ostringstream actions;
  actions << " 'until:s.maps_received >= 20 && s.tracks.length > 0 && s.objects_drawn > 0'"
          << " state:" << s1.string() << " wait:3 state:" << s2.string() << " wait:3 state:" << s2b.string()
          << " shot:" << (dir.path() / "view.png").string()
          << " run:sh\\ " << kill_root.string()
          << " 'until:!s.root_connected && s.banner.includes(\"Root unreachable\")'"
          << " state:" << s3.string() << " shot:" << (dir.path() / "root-lost.png").string()
          << " 'eval:window.fogmapMark = window.fogmapState.maps_received + 10'"
          << " run:sh\\ " << start_root.string()
          << " 'until:s.root_connected && s.banner === \"\" && s.maps_received >= window.fogmapMark'"
          << " state:" << s4.string() << " run:sh\\ " << scrape.string() << "\\ a wait:5 run:sh\\ " << scrape.string() << "\\ b"
          << " open:2 'until:s.maps_received >= 10' run:sh\\ " << scrape.string() << "\\ c wait:5 run:sh\\ " << scrape.string()
          << "\\ d states:" << pages.string();
  const std::string script = actions.str();
  const auto driven = runCommand("python3 " + kDriver + " " + url + " --timeout 60" + script);
  std::printf("%s", driven.second.c_str());
  ASSERT_EQ(driven.first, 0) << "the browser session failed; the view said:\n" << test_support::readFile(view_log);

  // The page drew the scene: objects, tracks with labels, and the tracks moved between two reads.
  const json first = readJson(s1), later = readJson(s2);
  ASSERT_TRUE(first.is_object() && later.is_object());
  EXPECT_TRUE(later["sse_connected"].get<bool>());
  EXPECT_TRUE(later["root_connected"].get<bool>());
  EXPECT_TRUE(later["tracker_connected"].get<bool>());
  EXPECT_GT(later["epoch"].get<long>(), first["epoch"].get<long>());
  EXPECT_GT(later["maps_received"].get<long>(), first["maps_received"].get<long>() + 10);
  EXPECT_GT(later["objects_drawn"].get<long>(), 0);
  // A track kept its id and moved, over one of two 3 s intervals. The scene starts again every
  // duration_s (60 s, on the wall clock): everything jumps back and every track is replaced, which
  // one of two consecutive intervals may span, never both. The page's first list counts too
  // (those of its first read may have been tentative tracks a loaded machine's first frames made
  // and dropped).
  const json last = readJson(s2b);
  ASSERT_TRUE(last.is_object());
  double moved = 0.0;
  const auto most_moved = [&](const json& before, const json& after) {
    for (const auto& now : after) {
      for (const auto& then : before) {
        if (now["id"] != then["id"]) continue;
        const double dx = now["x"].get<double>() - then["x"].get<double>(), dy = now["y"].get<double>() - then["y"].get<double>();
        moved = std::max(moved, std::hypot(dx, dy));
      }
    }
  };
  most_moved(first["tracks"], later["tracks"]);
  most_moved(later["first_tracks"], later["tracks"]);
  most_moved(later["tracks"], last["tracks"]);
  EXPECT_GT(moved, 1.0) << "a track kept its id and moved over 3 s; tracks at three reads 3 s apart: " << first["tracks"]
                        << ", " << later["tracks"] << ", " << last["tracks"];
  // From the root's publication to the page drawn, per map (epoch timestamps, one clock).
  auto latencies = later["latencies_ms"].get<std::vector<double>>();
  ASSERT_GT(latencies.size(), 20U);
  latencies.erase(latencies.begin(), latencies.begin() + 10);  // while the page was still loading
  std::printf("  epoch published at the root -> page drawn: %zu maps, p50 %.1f ms, p99 %.1f ms, max %.1f ms\n", latencies.size(),
              harness::percentile(latencies, 0.5), harness::percentile(latencies, 0.99), harness::percentile(latencies, 1.0));

  // The root went away: the page said so; it came back: the page recovered by itself.
  const json lost = readJson(s3), back = readJson(s4);
  EXPECT_FALSE(lost["root_connected"].get<bool>());
  EXPECT_TRUE(lost["sse_connected"].get<bool>()) << "the view itself stayed up";
  EXPECT_TRUE(back["root_connected"].get<bool>());
  EXPECT_GT(back["epoch"].get<long>(), lost["epoch"].get<long>());

  // Three browsers at once, every one live (ten: docs/design.md, "The live view").
  const json all = readJson(pages);
  ASSERT_TRUE(all.is_array());
  EXPECT_EQ(all.size(), 3U);
  for (const auto& page : all) EXPECT_GE(page["maps_received"].get<long>(), 10);
  // Pages cost the root nothing: they read the view, and the view is one subscriber. Its
  // publication (the root's end-to-end latency, sensor time to published) over 5 s with one page
  // and over 5 s with three, for the record (the browsers share this machine's cores with it).
  const auto mean_ms = [&](const char* from, const char* to) {
    const auto read = [&](const char* name, const std::string& family) {
      return harness::sumMetric(test_support::readFile(dir.path() / ("metrics-" + std::string(name) + ".txt")), family);
    };
    const double n = read(to, "fogmap_end_to_end_seconds_count") - read(from, "fogmap_end_to_end_seconds_count");
    return n > 0 ? 1e3 * (read(to, "fogmap_end_to_end_seconds_sum") - read(from, "fogmap_end_to_end_seconds_sum")) / n : -1.0;
  };
  std::printf("  the root's end-to-end latency, mean over 5 s: one page %.1f ms, three browsers %.1f ms\n", mean_ms("a", "b"),
              mean_ms("c", "d"));
}

}  // namespace
}  // namespace fogmap
