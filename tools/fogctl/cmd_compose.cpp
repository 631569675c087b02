// fogctl compose: a docker compose deployment of a topology (harness/compose.hpp).
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <utility>
#include <string>
#include <string_view>

#include "common/config/topology.hpp"
#include "harness/compose.hpp"
#include "harness/launcher.hpp"
#include "tools/fogctl/args.hpp"
#include "tools/fogctl/commands.hpp"

namespace fogmap::cli {
namespace {

using harness::ComposeOptions;
using harness::PrometheusOptions;
using harness::composeFile;
using harness::loadStartableTopology;
using harness::prometheusConfig;

namespace fs = std::filesystem;

Status writeText(const fs::path& path, const std::string& text) {
  std::error_code ec;
  if (path.has_parent_path()) fs::create_directories(path.parent_path(), ec);
  std::ofstream out(path);
  out << text;
  out.close();
  if (!out) return ioError("cannot write " + path.string());
  return {};
}

// `path` taken from the working directory, normal ("." is the directory itself).
Expected<fs::path> absolutePath(const fs::path& path) {
  std::error_code ec;
  const fs::path absolute = fs::absolute(path, ec);
  if (ec) return ioError("cannot resolve " + path.string() + ": " + ec.message());
  fs::path normal = absolute.lexically_normal();
  if (!normal.has_filename() && normal.has_parent_path() && normal != normal.root_path()) normal = normal.parent_path();
  return normal;
}

int runCompose(int argc, char** argv) {
  const std::string usage =
      "usage: fogctl compose TOPOLOGY.yaml [--out FILE] [--prometheus FILE] [--image NAME] [--prometheus-listen ADDR]\n"
      "                     [--grafana-listen ADDR] [--view-listen ADDR] [--check]";
  const auto args =
      Args::parse(argc, argv, 2, {"out", "prometheus", "image", "prometheus-listen", "grafana-listen", "view-listen"}, {"check"});
  if (!args) return fail(args.error(), "fogctl compose");
  if (args->positional().size() != 1) return fail(invalidArgument(usage), "fogctl compose");
  const fs::path topology_file = args->positional()[0];
  // Checked as fogctl up checks it: what would not start as a process does not start as a container.
  const auto topology = loadStartableTopology(topology_file);
  if (!topology) return fail(topology.error(), "fogctl compose");

  std::string command = "fogctl compose";
  for (int i = 2; i < argc; ++i) {
    if (std::string_view(argv[i]) != "--check") command += std::string(" ") + argv[i];
  }

  ComposeOptions options;
  options.topology_file = topology_file;
  for (const char* flag : {"out", "prometheus"}) {
    if (args->has(flag) && args->get(flag).empty()) {
      return fail(invalidArgument(std::string("--") + flag + " needs a file name"), "fogctl compose");
    }
  }
  const auto project_dir = absolutePath(args->has("out") ? fs::path(args->get("out")) : fs::path("."));
  if (!project_dir) return fail(project_dir.error(), "fogctl compose");
  options.project_dir = args->has("out") ? project_dir->parent_path() : *project_dir;
  const fs::path prometheus =
      args->has("prometheus") ? fs::path(args->get("prometheus")) : fs::path("docker/prometheus") / (topology->name + ".yml");
  const auto prometheus_path = absolutePath(prometheus);
  if (!prometheus_path) return fail(prometheus_path.error(), "fogctl compose");
  options.prometheus_config = prometheus_path->lexically_relative(options.project_dir);
  options.image = args->get("image", options.image);
  options.prometheus_listen = args->get("prometheus-listen", options.prometheus_listen);
  options.grafana_listen = args->get("grafana-listen", options.grafana_listen);
  options.view_listen = args->get("view-listen", options.view_listen);
  for (const std::string* listen : {&options.prometheus_listen, &options.grafana_listen, &options.view_listen}) {
    const auto colon = listen->rfind(':');
    if (colon == std::string::npos || colon == 0 || colon + 1 == listen->size()) {
      return fail(invalidArgument("'" + *listen + "' is not HOST:PORT"), "fogctl compose");
    }
  }
  options.command = command;
  const auto compose = composeFile(*topology, options);
  if (!compose) return fail(compose.error(), "fogctl compose");

  PrometheusOptions scrape;
  scrape.rule_files = {"/fogmap/docker/prometheus/rules.yml"};
  scrape.command = command;
  if (args->has("check")) {  // compare with the files, write nothing
    if (!args->has("out")) return fail(invalidArgument("--check needs --out"), "fogctl compose");
    bool current = true;
    for (const auto& [path, text] : {std::pair{fs::path(args->get("out")), *compose},
                                     std::pair{prometheus, prometheusConfig(*topology, scrape)}}) {
      std::ifstream in(path);
      const std::string on_disk((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      if (on_disk != text) {
        std::cerr << "fogctl compose: " << path.string() << " is not what the topology generates\n";
        current = false;
      }
    }
    if (!current) {
      std::cerr << "fogctl compose: generate again with: " << command << "\n";
      return 1;
    }
    std::cout << args->get("out") << " and " << prometheus.string() << " are current\n";
    return 0;
  }
  if (const Status written = writeText(prometheus, prometheusConfig(*topology, scrape)); !written.ok()) {
    return fail(written.error(), "fogctl compose");
  }
  if (!args->has("out")) {
    std::cout << *compose;
    std::cerr << "fogctl compose: the Prometheus configuration is in " << prometheus.string() << "\n";
    return 0;
  }
  if (const Status written = writeText(args->get("out"), *compose); !written.ok()) return fail(written.error(), "fogctl compose");
  std::cout << "wrote " << args->get("out") << " and " << prometheus.string() << "\n";
  return 0;
}

}  // namespace

Command composeCommand() {
  return {"compose",
          "TOPOLOGY.yaml [--out FILE] [--prometheus FILE]   a docker compose deployment of the topology",
          "usage: fogctl compose TOPOLOGY.yaml [--out FILE] [--prometheus FILE] [--image fogmap:latest]\n"
          "                      [--prometheus-listen 127.0.0.1:9090] [--grafana-listen 127.0.0.1:3000]\n"
          "                      [--view-listen 127.0.0.1:8088] [--check]\n"
          "Writes a docker compose file (to stdout unless --out) that runs every node of the topology as a\n"
          "container of the fogmap image with host networking (each service listens where its topology entry\n"
          "says, as under fogctl up), the live view (fogctl view, its page on --view-listen), Prometheus\n"
          "scraping every service with the alert rules of docker/prometheus/rules.yml, and Grafana with the\n"
          "provisioned dashboard (profile grafana). The\n"
          "directory of the compose file is mounted read-only at /fogmap: the topology and every file it\n"
          "names must lie inside it. Also writes the Prometheus configuration the deployment uses. The\n"
          "topology is checked first as fogctl up checks it.\n"
          "  --prometheus FILE  where (default: docker/prometheus/NAME.yml, NAME the topology's name)\n"
          "  --image NAME       the fogmap image (default fogmap:latest, built from docker/Dockerfile)\n"
          "  --check            write nothing; exit 1 when --out or the Prometheus file differ from what\n"
          "                     the topology generates\n",
          runCompose};
}

}  // namespace fogmap::cli
