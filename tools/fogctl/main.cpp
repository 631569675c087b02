// fogctl: the command-line front of fogmap.
#include <cstdio>
#include <cstring>
#include <exception>
#include <string>
#include <vector>

#include "common/cloud_io.hpp"
#include "tools/fogctl/commands.hpp"

namespace {

// The client identity flags of the commands that talk to the root.
constexpr const char* kTlsFlags =
    "With TLS (the topology's tls section) fogctl presents a client certificate:\n"
    "  --identity NAME  NAME.crt and NAME.key in the topology's tls.cert_dir (default: operator)\n"
    "  --cert FILE --key FILE --ca FILE   explicit files instead (with --target, no topology needed)\n";

struct Command {
  std::string name;
  std::string synopsis;  // its line in `fogctl --help`
  std::string usage;     // `fogctl NAME --help`
  int (*run)(int, char**);
};

const std::vector<Command>& commands() {
  static const std::vector<Command> all = {
      {"cluster",
       "--input SCAN [--eps 0.35] [--min-points 10] [--labels OUT.txt] [--method fogmap|pcl] [--remove-ground] [--threads N]",
       "usage: fogctl cluster --input SCAN [--eps 0.35] [--min-points 10] [--labels OUT.txt] [--method fogmap|pcl]\n"
       "                      [--remove-ground] [--threads N] [--max-scan-bytes N]\n"
       "Clusters one scan (KITTI .bin, nuScenes .pcd.bin, PCD) and prints the number of clusters.\n"
       "  --eps M              clustering radius in metres, 0.001 to 100 (default 0.35)\n"
       "  --min-points N       smallest cluster, in points (default 10)\n"
       "  --labels FILE        one label per point of the file, in its order: the cluster, -1 for noise\n"
       "                       (non-finite points are noise); with --remove-ground, per non-ground point\n"
       "  --method fogmap|pcl  fogmap's grid clustering or PCL's, the reference (default fogmap)\n"
       "  --remove-ground      remove the ground before clustering\n"
       "  --threads N          threads for the neighbour search (default: one per core)\n"
       "  --max-scan-bytes N   refuse larger files unread (default " + std::to_string(fogmap::kDefaultMaxScanBytes) + ")\n",
       fogmap::cli::runCluster},
      {"bench",
       "clustering --input SCAN [--eps 0.35] [--min-points 10] [--remove-ground] [--repeat 5] [--threads N] [--json]",
       "usage: fogctl bench clustering --input SCAN [--eps 0.35] [--min-points 10] [--remove-ground] [--repeat 5]\n"
       "                               [--threads N] [--json] [--max-scan-bytes N]\n"
       "Times fogmap's clustering against PCL's on one scan (median of --repeat runs) and checks that\n"
       "both give the same partition; exits 1 when they do not.\n",
       fogmap::cli::runBench},
      {"demo",
       "[--input DIR | --scene FILE] [--nodes 4] [--topology star|tree] [--frames 20] [--report FILE] [--png FILE]",
       "usage: fogctl demo [--input DIR] [--nodes 4] [--topology star|tree] [--frames 20] [--report FILE] [--png FILE]\n"
       "                   [--alpha 1.5] [--base-port 46000] [--state DIR]\n"
       "       fogctl demo --scene FILE [--topology star|tree] [--frames 10] [--report FILE] [--png FILE] [--alpha 1.5]\n"
       "                   [--base-port 46000] [--state DIR] [--miss-rate 0.3] [--association kalman|paper]\n"
       "                   [--tracker-input global_map|centroids] [--track-frames 100] [--tracks-png FILE]\n"
       "Runs a local MAD-C cluster and the baseline over the same frames and compares them: bytes,\n"
       "latency, Rand index; writes a JSON report and a bird's-eye PNG (under --state, default .fogmap/demo).\n"
       "  --input DIR    recorded scans (default: the bundled KITTI frames), cut into --nodes virtual LiDARs\n"
       "  --scene FILE   a simulated scene (fogctl scene): one edge per LiDAR of the scene, MAD-C-ext and the\n"
       "                 baseline over its first --frames frames (replayed in a loop, so both see the same\n"
       "                 frames), both also scored against the scene's truth (Rand index, ARI, objects found\n"
       "                 whole, split, merged, missed). When something in the scene moves and it has cameras,\n"
       "                 then also the cluster of fogctl topology --scene FILE --tracker: the tracker and a\n"
       "                 detection service per camera replaying the truth (--miss-rate of it missed, 2 px box\n"
       "                 jitter, 50 ms latency); after 30 track lists, --track-frames of them within one cycle\n"
       "                 of the scene are scored against the truth (CLEAR MOT, IDF1, localization error, sensor\n"
       "                 time to published tracks: the report's \"tracking\" object), and --tracks-png (default\n"
       "                 tracks.png under --state) shows the last with the tracks, their ids, labels and trails\n",
       fogmap::cli::runDemo},
      {"eval",
       "[--quick] [--out DIR] [--doc FILE] [--seed 1] [--frames N] [--no-links]   the MAD-C paper's evaluation and tracking",
       "usage: fogctl eval [--quick] [--out DIR] [--doc FILE] [--seed 1] [--frames N] [--no-links]\n"
       "Reproduces the MAD-C paper's evaluation with real clusters on simulated random scenes: ellipsoid\n"
       "precision/recall against alpha (Fig. 6), Rand index and ARI of MAD-C and MAD-C-ext against the\n"
       "baseline and the truth for 2, 3, 5, 7 LiDARs and alpha 0.8 .. 2.4 (Figs. 7, 8), ellipsoid comparisons\n"
       "with and without delimiting boxes for 10, 50, 100 objects (Table 1), bytes and stage times (Fig. 9),\n"
       "and end to end per frame with every edge behind a 10 Mbit/s link (tc tbf on veth pairs between\n"
       "network namespaces; needs root, else that part is SKIPPED with the reason). Then tracking: the\n"
       "fusion paper's association and fogmap's Kalman tracker side by side with 0, 30 and 60 % of the\n"
       "detections missing (fogctl track-eval's run: 6 people and 2 cars, 4 LiDARs, 4 cameras, 200 frames).\n"
       "Writes DIR/{accuracy,precision_recall,costs,links,tracking}.csv, DIR/eval.json, DIR/*.png and the report.\n"
       "  --quick      2 and 3 LiDARs, 10 and 30 objects, alpha 0.8, 1.5, 2.4; 3 LiDARs behind the links;\n"
       "               tracking of 4 people and a car for 60 frames; under two minutes\n"
       "  --out DIR    default docs/evaluation (full) or .fogmap/eval-quick (--quick)\n"
       "  --doc FILE   the Markdown report (default: docs/evaluation.md (full) or DIR/evaluation.md)\n"
       "  --frames N   complete frames per run (default 5, quick 4)\n"
       "  --no-links   skip the rate-limited links\n",
       fogmap::cli::runEval},
      {"track-eval",
       "[--people 6] [--vehicles 2] [--lidars 4] [--cameras 4] [--frames 200] [--seed 1] [--json FILE]   the fusion tracker",
       "usage: fogctl track-eval [--people 6] [--vehicles 2] [--lidars 4] [--cameras 4] [--frames 200] [--seed 1]\n"
       "                         [--visible-side-radius 0.4] [--merge-radius 1.0] [--json FILE]\n"
       "Runs the fusion tracker on a simulated moving scene (fogctl scene moving) through the real chain:\n"
       "each LiDAR's 10 Hz frames through its displacement detector, the centroids of one instant merged\n"
       "into one LiDAR frame, every camera's detections replayed from the truth (seeded misses, 2 px box\n"
       "jitter, 50 ms latency). The paper and kalman associations run for 0, 30 and 60 % missed detections\n"
       "on the same frames; prints MOTA, MOTP, ID switches, fragmentations, IDF1, localization error (also\n"
       "for people within 15 m of a LiDAR), tracks confirmed and the tracker's time per LiDAR frame.\n"
       "  --people N, --vehicles M   walking people and driving cars on crossing paths across 40 x 40 m\n"
       "  --lidars K   VLP-16s at the MAD-C paper's spots, 1 to 7; --cameras C   around the area, 0 to 6\n"
       "  --frames N   scored LiDAR frames (default 200: 20 s)\n"
       "  --visible-side-radius R   centroids narrower than R m are placed on the object's axis, not on the\n"
       "               side their LiDAR sees (0: as Algorithm 1 gives them; default 0.4)\n"
       "  --merge-radius M   centroids of one instant closer than M m are one observation (default 1.0)\n"
       "  --json FILE  every figure as JSON\n",
       fogmap::cli::runTrackEval},
      {"overlay",
       "--image IMG --calib CALIB --out PNG [--labels FILE] [--scan FILE [--objects]] [--hog]   draw on a camera frame",
       "usage: fogctl overlay --image IMG --calib CALIB --out PNG [--labels FILE] [--scan FILE [--objects]] [--hog]\n"
       "                      [--hog-upscale 1.5]\n"
       "Draws over a camera frame (KITTI camera 2) what fogmap knows: a LiDAR scan's points projected into\n"
       "the image (coloured by depth), the 3D boxes of a label_2 file as wireframes, and with --hog the\n"
       "people OpenCV's HOG detector finds; writes PNG. For checking a calibration and a detector by eye.\n"
       "  --calib FILE   KITTI calibration (P2, R0_rect, Tr_velo_to_cam)\n"
       "  --labels FILE  KITTI label_2 objects; --scan FILE  a Velodyne scan (.bin, .pcd)\n"
       "  --objects      instead of the scan's points, the map an edge makes of it (the ready-made KITTI\n"
       "                 topology's crop, ground and MAD-C): each object the box of its projected ellipsoids\n",
       fogmap::cli::runOverlay},
      {"up",
       "TOPOLOGY.yaml [--detach] [--state DIR] [--dry-run]   start every service as a local process",
       "usage: fogctl up TOPOLOGY.yaml [--detach] [--state DIR] [--timeout-s 30] [--dry-run]\n"
       "Starts every service of the topology as a local process and waits until each serves /metrics.\n"
       "First checks what each service checks before it starts (every camera's detector settings and\n"
       "model files, every file a node reads; not the TLS files) and refuses the topology naming the node\n"
       "and the field.\n"
       "  --dry-run      check, and print the command of every service it would start and where its log\n"
       "                 would go; start, create and write nothing\n"
       "  --detach       leave the cluster running and print the command that stops it\n"
       "  --state DIR    where the pids and logs go (default: .fogmap/NAME next to the topology file)\n"
       "  --timeout-s S  how long the services may take to start (default 30)\n",
       fogmap::cli::runUp},
      {"down",
       "TOPOLOGY.yaml | --state DIR                stop a detached cluster",
       "usage: fogctl down TOPOLOGY.yaml | --state DIR\n"
       "Stops a cluster started by fogctl up --detach. Only processes that are still the services fogctl\n"
       "started are signalled; records of processes that are gone or were replaced are reported and left alone.\n",
       fogmap::cli::runDown},
      {"watch",
       "TOPOLOGY.yaml | --target HOST:PORT [--tracks] [--count N]   print the live global map or tracks",
       "usage: fogctl watch TOPOLOGY.yaml | --target HOST:PORT [--tracks] [--count N] [--objects 10] [--idle-s 10] [--timeout-s 0]\n"
       "                    [--identity NAME | --cert FILE --key FILE --ca FILE]\n"
       "Prints the root aggregator's global maps as they come. A root that is still starting is tried again\n"
       "until it answers; exits 1 when it cannot be reached within --timeout-s (default 5 s), when it goes\n"
       "away, or after --timeout-s without a map.\n"
       "  --tracks       the tracks of the topology's tracker (or of the tracker at --target) instead:\n"
       "                 id, label, state, position, velocity, and whether a camera confirmed it\n"
       "  --count N      stop after N maps (default 0: until Ctrl-C)\n"
       "  --objects N    objects listed per map, the largest first (default 10)\n"
       "  --idle-s S     say so after every S seconds without a global map (default 10)\n"
       "  --timeout-s S  give up after S seconds without a global map (default 0: never)\n" +
           std::string(kTlsFlags),
       fogmap::cli::runWatch},
      {"geofence",
       "set|query TOPOLOGY.yaml | --target HOST:PORT [--name NAME] [--box XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX]",
       "usage: fogctl geofence set TOPOLOGY.yaml | --target HOST:PORT --name NAME --box XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX\n"
       "       fogctl geofence query TOPOLOGY.yaml | --target HOST:PORT [--name NAME]\n"
       "       (either one: [--identity NAME | --cert FILE --key FILE --ca FILE])\n"
       "set: defines (or replaces) a box geofence on the root aggregator; with TLS only the clients\n"
       "     the topology's tls.geofence_clients lists may.\n"
       "query: the objects of the latest global map inside or crossing the geofences (or the one named).\n" +
           std::string(kTlsFlags),
       fogmap::cli::runGeofence},
      {"faults",
       "TOPOLOGY.yaml --scenario soak|edge-crash|aggregator-crash|stall [--duration-s 60] [--seed 1] [--report FILE]",
       "usage: fogctl faults TOPOLOGY.yaml [--scenario soak|edge-crash|aggregator-crash|stall] [--duration-s 60]\n"
       "                     [--warmup-s 20] [--seed 1] [--kills 2] [--downtime-s S] [--report FILE] [--state DIR]\n"
       "                     [--stall-by sigstop|netns] [--no-oracle]\n"
       "Runs the topology as local processes under load, injects a fault at seeded times, and checks the\n"
       "root's global maps: every map an edge's parent acknowledged reaches the root, none is applied twice,\n"
       "every epoch is published, every global map equals the specification over its contributing nodes\n"
       "(mode madc), and the fault's own bounds. Exits 0 when every check passes, 1 otherwise.\n"
       "  --scenario S     soak (no fault), edge-crash (kill -9 of --kills edges, restarted after --downtime-s),\n"
       "                   aggregator-crash (kill -9 of one non-root aggregator, restarted after --downtime-s),\n"
       "                   stall (SIGSTOP of one non-root aggregator for --downtime-s, default 5)\n"
       "  --stall-by M     sigstop (default), or netns: the aggregator runs in a network namespace of its\n"
       "                   own and every packet of it is dropped with iptables (root, ip and iptables)\n"
       "  --duration-s S   how long the load runs (default 60); --warmup-s: RSS growth is measured after it\n"
       "  --seed N         chooses the victims and the times (default 1)\n"
       "  --report FILE    the JSON report (default STATE/NAME/faults.json)\n"
       "  --state DIR      logs, journals and the report (default .fogmap/faults next to the topology)\n"
       "  --no-oracle      skip the comparison with the specification (it recomputes every edge's maps)\n"
       "The long soak: fogctl topology tree --edges 8 --source data/kitti_raw_seq_a --out tree-8.yaml &&\n"
       "               fogctl faults tree-8.yaml --scenario soak --duration-s 600 --warmup-s 60\n",
       fogmap::cli::runFaults},
      {"certs",
       "TOPOLOGY.yaml --out DIR [--days 365] [--clients operator,...]   a CA and certificates for mutual TLS",
       "usage: fogctl certs TOPOLOGY.yaml --out DIR [--days 365] [--clients operator,...] [--owner UID] [--force]\n"
       "Makes a CA (DIR/ca.crt, ca.key) and a certificate for every node of the topology and every client\n"
       "named (DIR/NAME.crt, NAME.key; keys readable by their owner only), EC P-256, signed by the CA.\n"
       "A certificate's common name is its holder's identity; a node's also names its host (IP\n"
       "subjectAltName), so its peers verify HOST:PORT. Point the topology at them: tls: {ca: DIR/ca.crt}.\n"
       "  --days N       valid from now for N days (default 365)\n"
       "  --clients A,B  client identities besides the nodes, for fogctl --identity\n"
       "                 (default: operator and the topology's tls.geofence_clients)\n"
       "  --owner UID    give the nodes' private keys to UID (as root): the user the services run as,\n"
       "                 10001 in the fogmap image (fogctl compose)\n"
       "  --force        replace a CA already in DIR (what it issued is no longer trusted)\n",
       fogmap::cli::runCerts},
      {"compose",
       "TOPOLOGY.yaml [--out FILE] [--prometheus FILE]   a docker compose deployment of the topology",
       "usage: fogctl compose TOPOLOGY.yaml [--out FILE] [--prometheus FILE] [--image fogmap:latest]\n"
       "                      [--prometheus-listen 127.0.0.1:9090] [--grafana-listen 127.0.0.1:3000] [--check]\n"
       "Writes a docker compose file (to stdout unless --out) that runs every node of the topology as a\n"
       "container of the fogmap image with host networking (each service listens where its topology entry\n"
       "says, as under fogctl up), Prometheus scraping every service with the alert rules of\n"
       "docker/prometheus/rules.yml, and Grafana with the provisioned dashboard (profile grafana). The\n"
       "directory of the compose file is mounted read-only at /fogmap: the topology and every file it\n"
       "names must lie inside it. Also writes the Prometheus configuration the deployment uses. The\n"
       "topology is checked first as fogctl up checks it.\n"
       "  --prometheus FILE  where (default: docker/prometheus/NAME.yml, NAME the topology's name)\n"
       "  --image NAME       the fogmap image (default fogmap:latest, built from docker/Dockerfile)\n"
       "  --check            write nothing; exit 1 when --out or the Prometheus file differ from what\n"
       "                     the topology generates\n",
       fogmap::cli::runCompose},
      {"topology",
       "star|tree --edges K --source DIR | --scene FILE [--base-port P] [--mode madc|baseline|ext] [--frames N] [--out FILE]",
       "usage: fogctl topology star|tree --edges K --source DIR [--base-port 50000] [--mode madc|baseline|ext]\n"
       "                       [--frames N] [--fanout 2] [--deadline-ms 80] [--tls-ca FILE]\n"
       "                       [--tracker [--association paper|kalman] [--cameras DIR[,DIR...] [--calib FILE]\n"
       "                       [--camera-rate-hz 10]]] [--out FILE]\n"
       "       fogctl topology [star|tree] --scene FILE [the same flags but --edges, --source and --cameras]\n"
       "Writes a topology file: K virtual LiDARs cut from the scans in DIR, under one sink (star) or a\n"
       "tree of aggregators; to stdout unless --out. Paths are relative to the topology file, whose\n"
       "directory is --out's (the working directory without --out).\n"
       "  --tracker        also a tracker (named tracker, port P+300, metrics P+301) that reads the root's\n"
       "                   global maps and publishes tracks (fogctl watch --tracks); --association paper|kalman\n"
       "                   (default kalman)\n"
       "  --cameras DIRS   with --tracker: a detection node per directory of KITTI camera frames named\n"
       "                   image_0N (node cam-image_0N, metrics P+401, ...), running OpenCV's HOG people\n"
       "                   detector on them at --camera-rate-hz R (10), calibrated as camera N of --calib FILE\n"
       "                   (default: calib.txt beside DIR, KITTI raw's layout) in the scans' frame; the files\n"
       "                   are read now (the calibration, the first image's size)\n"
       "  --scene FILE     instead of scans: one edge per LiDAR of the scene (fogctl scene), named\n"
       "                   edge-<LiDAR name>, ids 1..K, each simulating its LiDAR (sensor source sim) at the\n"
       "                   LiDAR's pose in the scene, at 10 Hz; a star unless tree is given. The scene is\n"
       "                   written relative to --out's directory (the working directory without --out)\n"
       "  --tracker        with --scene: the tracker and a detection node per camera of the scene\n"
       "                   (cam-<camera>), calibrated as the scene says, replaying the scene's objects as\n"
       "                   detections (detector truth) with --miss-rate R (0), --box-jitter-px S (0) and\n"
       "                   --latency-ms L (0); --tracker-input centroids: every edge streams the tracker\n"
       "                   the displacement centroids of its scans instead of the root's maps (global_map)\n"
       "  --fanout F       a tree's aggregators have at most F children (default 2)\n"
       "  --deadline-ms D  an aggregator's deadline per level (default 80)\n"
       "  --tls-ca FILE    mutual TLS on every link, certificates next to FILE (fogctl certs)\n",
       fogmap::cli::runTopology},
      {"scene",
       "random|factory|moving [...] [--seed S] [--out FILE]   a simulated scene with ground truth",
       "usage: fogctl scene random --objects N --lidars K [--seed 1] [--out FILE]\n"
       "       fogctl scene factory [--seed 1] [--out FILE]\n"
       "       fogctl scene moving --people N --vehicles M --lidars K --cameras C [--seed 1] [--out FILE]\n"
       "Writes a scene file (format: data/scenes/example.yaml) made from the seed; to stdout unless --out.\n"
       "  random   N objects from 0.8 m crates to cars, people and poles, placed apart and turned at random\n"
       "           on 50 x 50 m; K HDL-32E LiDARs at the MAD-C paper's spots (Lambda_1 .. Lambda_7)\n"
       "  factory  shelves, forklifts driving the aisles, people walking, a crane; LiDARs in the four\n"
       "           corners and the middle\n"
       "  moving   people and vehicles on crossing and parallel paths across 40 x 40 m, K VLP-16 LiDARs and\n"
       "           C cameras around the area looking inwards\n",
       fogmap::cli::runScene},
      {"split",
       "--input SCAN --views K [--overlap-deg 10] --out DIR   cut a scan into virtual LiDARs",
       "usage: fogctl split --input SCAN --views K [--overlap-deg 10] --out DIR\n"
       "Cuts a scan into K overlapping sectors, one KITTI .bin per virtual LiDAR, and prints their poses.\n",
       fogmap::cli::runSplit},
  };
  return all;
}

void usage(std::FILE* to) {
  std::fprintf(to, "usage: fogctl <command> [flags]\n");
  for (const auto& c : commands()) std::fprintf(to, "  %s %s\n", c.name.c_str(), c.synopsis.c_str());
  std::fprintf(to, "fogctl <command> --help (or fogctl help <command>) describes a command's flags.\n");
}

const Command* find(const std::string& name) {
  for (const auto& c : commands()) {
    if (c.name == name) return &c;
  }
  return nullptr;
}

bool asksForHelp(int argc, char** argv) {
  for (int i = 2; i < argc; ++i) {
    if (std::strcmp(argv[i], "--help") == 0 || std::strcmp(argv[i], "-h") == 0) return true;
  }
  return false;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    usage(stderr);
    return 2;
  }
  const std::string first = argv[1];
  if (first == "--help" || first == "-h" || first == "help") {
    if (first == "help" && argc > 2) {
      const Command* c = find(argv[2]);
      if (c == nullptr) {
        std::fprintf(stderr, "fogctl: unknown command '%s'\n", argv[2]);
        usage(stderr);
        return 2;
      }
      std::fputs(c->usage.c_str(), stdout);
      return 0;
    }
    usage(stdout);
    return 0;
  }
  const Command* command = find(first);
  if (command == nullptr) {
    std::fprintf(stderr, "fogctl: unknown command '%s'\n", first.c_str());
    usage(stderr);
    return 2;
  }
  if (asksForHelp(argc, argv)) {
    std::fputs(command->usage.c_str(), stdout);
    return 0;
  }
  try {
    return command->run(argc, argv);
  } catch (const std::exception& e) {
    // The commands return errors as values; this only keeps one that escapes from aborting.
    std::fprintf(stderr, "fogctl %s: %s\n", first.c_str(), e.what());
    return 1;
  }
}
