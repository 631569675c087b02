#include "harness/scene_run.hpp"

#include <algorithm>
#include <fstream>
#include <numeric>
#include <set>
#include <sstream>
#include <unistd.h>

#include <grpcpp/grpcpp.h>

#include "common/base/angles.hpp"
#include "common/base/clock.hpp"
#include "common/base/epochs.hpp"
#include "common/certs/certs.hpp"
#include "common/geometry/map.hpp"
#include "common/sim/scene_topology.hpp"
#include "common/sim/sensor_frames.hpp"
#include "fogmap/v1/fogmap.grpc.pb.h"
#include "harness/evaluation.hpp"
#include "harness/free_ports.hpp"
#include "harness/report_text.hpp"
#include "harness/shaped_links.hpp"
#include "services/common/grpc_options.hpp"
#include "services/common/proto_convert.hpp"
#include "services/edge_cluster/edge_runner.hpp"

namespace fogmap::harness {
namespace {

double mean(const std::vector<double>& v) {
  return v.empty() ? 0.0 : std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
}

RandScores meanScores(const std::vector<RandScores>& v) {
  RandScores out{0.0, 0.0};
  if (v.empty()) return out;
  for (const auto& s : v) {
    out.rand_index += s.rand_index;
    out.adjusted_rand_index += s.adjusted_rand_index;
  }
  out.rand_index /= static_cast<double>(v.size());
  out.adjusted_rand_index /= static_cast<double>(v.size());
  return out;
}

// The scene instant of a run's epoch: sim::sceneTime of the scan number its edges replayed.
Expected<double> sceneTimeOfEpoch(const sim::Scene& scene, const TopologyConfig& topology, std::uint64_t epoch) {
  const auto schedule = EpochSchedule::create(topology.period_ms, topology.deadline_ms);
  if (!schedule) return schedule.error();
  const double rate = 1000.0 / topology.period_ms;
  return sim::sceneTime(scene, scanNumberAt(*schedule, rate, epoch), rate);
}

std::vector<double> endToEndMs(const RunResult& run) {
  std::vector<double> out;
  for (const auto& [e, g] : run.epochs) {
    if (completeEpoch(g)) out.push_back(nsToMs(g.published_time_ns - g.header.sensor_time_ns));
  }
  return out;
}

double sumOver(const RunResult& run, const TopologyConfig& topology, Role role, const std::string& family) {
  double total = 0.0;
  for (const auto& n : topology.nodes) {
    const auto page = run.metrics.find(n.name);
    if (n.role == role && page != run.metrics.end()) total += sumMetric(page->second, family);
  }
  return total;
}

double meanOver(const RunResult& run, const TopologyConfig& topology, Role role, const std::string& family) {
  const double sum = sumOver(run, topology, role, family + "_sum");
  const double count = sumOver(run, topology, role, family + "_count");
  return count > 0.0 ? sum / count : 0.0;
}

}  // namespace

double endToEndP50Ms(const SceneRun& run) { return percentile(endToEndMs(run.result), 0.5); }

Expected<std::filesystem::path> writeCycledScene(const std::filesystem::path& dir, sim::Scene& scene,
                                                 std::uint64_t cycle_frames, double rate_hz) {
  if (cycle_frames == 0 || !(rate_hz > 0.0)) return invalidArgument("a scene cycle needs frames and a positive rate");
  scene.duration_s = static_cast<double>(cycle_frames) / rate_hz;
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  const auto file = std::filesystem::absolute(dir / "scene.yaml");
  std::ofstream out(file);
  out << sim::toYaml(scene);
  if (!out) return ioError("cannot write " + file.string());
  return file;
}

Expected<SceneRun> runScene(const std::filesystem::path& dir, const std::filesystem::path& scene_file,
                            const sim::Scene& scene, const SceneRunOptions& options) {
  sim::SceneTopologyOptions layout;
  layout.tree = options.tree;
  layout.fanout = options.fanout;
  layout.base_port = options.base_port;
  layout.rate_hz = options.rate_hz;
  layout.mapping = options.mapping;
  TopologyConfig topology = sim::sceneTopology(scene, scene_file, layout);
  topology.mode = options.mode;
  topology.baseline_ships_raw = options.mode == Mode::kBaseline && options.baseline_raw;
  topology.madc.alpha = options.alpha;
  topology.name = std::string(modeName(options.mode)) + (topology.baseline_ships_raw ? "-raw-" : "-") +
                  std::to_string(scene.lidars.size()) + "lidars";
  topology.period_ms = 1000.0 / options.rate_hz;
  // Slow links need the time to carry a frame; locally an epoch's maps arrive within milliseconds.
  if (options.link_mbit) topology.deadline_ms = std::max(topology.deadline_ms, 0.9 * topology.period_ms);
  for (auto& n : topology.nodes) {
    if (n.sensor) n.sensor->frames.reset();  // the edges run until stopped, so their metrics can be read
  }
  if (options.free_ports) {
    try {
      useFreePorts(topology);
    } catch (const std::exception& e) {
      return Error{ErrorCode::kInternal, e.what()};
    }
  }
  RunOptions run;
  run.frames = 100000;
  // A complete epoch of every frame of the scene's cycle (of `frames` frames when the scene was
  // cycled so): a busy machine that leaves some epochs incomplete does not leave a frame unscored,
  // so MAD-C and the baseline runs pair frame for frame.
  const auto schedule = EpochSchedule::create(topology.period_ms, topology.deadline_ms);
  if (!schedule) return schedule.error();
  run.enough = [&scene, schedule = *schedule, rate = options.rate_hz, frames = options.frames](const RunResult& result) {
    std::set<std::uint64_t> seen;
    for (const std::uint64_t e : completeEpochs(result)) seen.insert(sim::cycleFrame(scene, scanNumberAt(schedule, rate, e), rate));
    return seen.size() >= frames;
  };
  run.point_labels = options.mode == Mode::kBaseline;
  run.timeout = std::chrono::seconds(40) +
                std::chrono::milliseconds(static_cast<long>(4.0 * topology.period_ms * static_cast<double>(options.frames)));
  std::optional<ShapedLinks> shaped;
  TopologyConfig ran = topology;
  if (options.link_mbit) {
    if (Status possible = shapingAvailable(); !possible) return possible.error();
    auto links = ShapedLinks::create(topology, *options.link_mbit, static_cast<unsigned>(::getpid()));
    if (!links) return links.error();
    shaped.emplace(std::move(*links));
    ran = shaped->topology();
    run.prefixes = shaped->prefixes();
  }
  auto result = runCluster(dir, ran, run);
  if (!result) return result.error();
  return SceneRun{std::move(ran), std::move(*result)};
}

Expected<SceneScores> scoreSceneRuns(const sim::Scene& scene, const SceneRun& madc, const SceneRun* baseline) {
  const auto schedule = EpochSchedule::create(madc.topology.period_ms, madc.topology.deadline_ms);
  if (!schedule) return schedule.error();
  const double rate = 1000.0 / madc.topology.period_ms;
  const auto cycle = [&](const EpochSchedule& s, std::uint64_t epoch) {
    return sim::cycleFrame(scene, scanNumberAt(s, rate, epoch), rate);
  };
  std::map<std::uint64_t, const GlobalMapMessage*> baseline_by_frame;
  if (baseline != nullptr) {
    const auto base_schedule = EpochSchedule::create(baseline->topology.period_ms, baseline->topology.deadline_ms);
    if (!base_schedule) return base_schedule.error();
    for (const auto& [e, g] : baseline->result.epochs) {
      if (completeEpoch(g)) baseline_by_frame.emplace(cycle(*base_schedule, e), &g);
    }
  }
  // One complete epoch per frame of the scene's cycle (the first): a run that waited for every frame
  // of the cycle may hold several of some, and each frame weighs the same in the scores.
  std::vector<std::uint64_t> epochs;
  {
    std::set<std::uint64_t> scored;
    for (const std::uint64_t e : completeEpochs(madc.result)) {
      if (scored.insert(cycle(*schedule, e)).second) epochs.push_back(e);
    }
  }
  if (epochs.empty()) return Error{ErrorCode::kInternal, "no complete MAD-C epoch to score"};
  auto views = recomputeEdges(madc.topology, epochs);
  if (!views) return views.error();

  SceneScores out;
  out.madc_breakdown = emptyBreakdown(scene);
  out.baseline_breakdown = emptyBreakdown(scene);
  std::vector<RandScores> vs_baseline;
  std::vector<RandScores> ext_vs_baseline;
  std::vector<RandScores> madc_truth;
  std::vector<RandScores> baseline_truth;
  std::vector<double> baseline_bytes;
  std::vector<double> raw_bytes;
  std::vector<double> objects;
  std::vector<double> true_objects;
  std::vector<double> pairs_tested;
  std::vector<double> pairs_all;
  for (const auto e : epochs) {
    const GlobalMapMessage& g = madc.result.epochs.at(e);
    const EdgeView& view = views->at(e);
    const auto truth = scoreAgainstTruth(madcPointObjects(g, view), view);
    if (!truth) return truth.error();
    madc_truth.push_back(truth->points);
    addObjectMatch(out.madc_objects, truth->objects);
    // Every true object where it is at the frame's instant (the view's truth is of that instant).
    const auto time_s = sceneTimeOfEpoch(scene, madc.topology, e);
    if (!time_s) return time_s.error();
    const auto madc_breakdown = breakDownObjects(scene, *time_s, truth->outcomes);
    if (!madc_breakdown) return madc_breakdown.error();
    addBreakdown(out.madc_breakdown, *madc_breakdown);
    true_objects.push_back(static_cast<double>(truth->objects.objects_true));
    objects.push_back(static_cast<double>(g.map.objects.size()));
    out.madc_wire.add(view);
    baseline_bytes.push_back(static_cast<double>(view.baseline_bytes));
    raw_bytes.push_back(static_cast<double>(view.raw_bytes));
    // Table 1: the MERGE of the maps the edges shipped, as the root merged them (the same partition).
    const MergeResult merged = mergeAll(view.local_maps);
    pairs_tested.push_back(static_cast<double>(merged.stats.pairs_tested));
    pairs_all.push_back(static_cast<double>(merged.stats.pairs_all));
    ++out.frames;

    const auto pair = baseline_by_frame.find(cycle(*schedule, e));
    if (pair == baseline_by_frame.end()) continue;
    const Accuracy a = accuracy(g, *pair->second, view);
    const auto base_objects = baselinePointObjects(*pair->second, view);
    if (!a.ok || !base_objects) continue;
    const auto base_truth = scoreAgainstTruth(*base_objects, view);
    if (!base_truth) return base_truth.error();
    vs_baseline.push_back(a.clusters);
    ext_vs_baseline.push_back(a.points);
    baseline_truth.push_back(base_truth->points);
    addObjectMatch(out.baseline_objects, base_truth->objects);
    const auto base_breakdown = breakDownObjects(scene, *time_s, base_truth->outcomes);
    if (!base_breakdown) return base_breakdown.error();
    addBreakdown(out.baseline_breakdown, *base_breakdown);
    ++out.frames_vs_baseline;
  }
  out.madc_vs_baseline = meanScores(vs_baseline);
  out.ext_vs_baseline = meanScores(ext_vs_baseline);
  out.madc_vs_truth = meanScores(madc_truth);
  out.baseline_vs_truth = meanScores(baseline_truth);
  out.madc_bytes_per_frame = out.madc_wire.bytesPerFrame(out.frames);
  out.baseline_bytes_per_frame = mean(baseline_bytes);
  out.raw_bytes_per_frame = mean(raw_bytes);
  out.global_objects = mean(objects);
  out.true_objects = mean(true_objects);
  out.pairs_tested_per_epoch = mean(pairs_tested);
  out.pairs_all_per_epoch = mean(pairs_all);
  out.clustering_ms = meanOver(madc.result, madc.topology, Role::kEdge, "fogmap_clustering_seconds") * 1e3;
  out.merge_ms = meanOver(madc.result, madc.topology, Role::kAggregator, "fogmap_merge_seconds") * 1e3;
  out.madc_e2e_p50_ms = percentile(endToEndMs(madc.result), 0.5);
  out.madc_bytes_measured = madc.result.bytes_moved;
  if (baseline != nullptr) {
    out.baseline_clustering_ms =
        meanOver(baseline->result, baseline->topology, Role::kAggregator, "fogmap_merge_seconds") * 1e3;
    out.baseline_e2e_p50_ms = percentile(endToEndMs(baseline->result), 0.5);
    out.baseline_bytes_measured = baseline->result.bytes_moved;
  }
  return out;
}

Expected<std::pair<std::uint64_t, EdgeView>> lastCompleteView(const SceneRun& run) {
  for (auto it = run.result.epochs.rbegin(); it != run.result.epochs.rend(); ++it) {
    if (!completeEpoch(it->second)) continue;
    auto views = recomputeEdges(run.topology, {it->first});
    if (!views) return views.error();
    return std::pair{it->first, std::move(views->at(it->first))};
  }
  return Error{ErrorCode::kInternal, "no complete epoch"};
}

Expected<std::vector<Eigen::Vector2d>> missedObjectCentres(const sim::Scene& scene, const SceneRun& madc, std::uint64_t epoch,
                                                           const EdgeView& view) {
  const auto global = madc.result.epochs.find(epoch);
  if (global == madc.result.epochs.end()) {
    return Error{ErrorCode::kNotFound, "the root published no global map for epoch " + std::to_string(epoch)};
  }
  const auto truth = scoreAgainstTruth(madcPointObjects(global->second, view), view);
  if (!truth) return truth.error();
  const auto time_s = sceneTimeOfEpoch(scene, madc.topology, epoch);
  if (!time_s) return time_s.error();
  return missedCentres(scene, *time_s, truth->outcomes);
}

bool tracksScene(const sim::Scene& scene) { return !scene.cameras.empty() && !movingObjects(scene).empty(); }

namespace {

// Reads the tracker's stream into `lists` until they hold the scoring window, the deadline passes
// or a stop is asked for. Returns why it ended early (empty when the window is there).
std::string readTracks(const TopologyConfig& topology, const sim::Scene& scene, const EpochSchedule& schedule,
                       double rate_hz, const SceneTrackingOptions& options, std::chrono::steady_clock::time_point deadline,
                       std::vector<PublishedTracks>& lists) {
  const NodeConfig* tracker = topology.find("tracker");
  if (tracker == nullptr) return "the topology has no tracker";
  const auto tls = loadTls(topology, "operator", std::chrono::system_clock::now());
  if (!tls) return "tls: " + tls.error().message;
  const std::string target = endpoint(tracker->host, tracker->port);
  std::vector<double> times;
  // One subscription, re-opened while the tracker starts listening or if it drops the stream.
  while (std::chrono::steady_clock::now() < deadline && !stopRequested()) {
    auto channel = makeChannel(target, channelCredentials(*tls), 64U << 20);
    if (!channel->WaitForConnected(std::chrono::system_clock::now() + std::chrono::milliseconds(200))) continue;
    auto stub = v1::TrackerService::NewStub(channel);
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() +
                         std::chrono::duration_cast<std::chrono::system_clock::duration>(deadline - std::chrono::steady_clock::now()));
    v1::TrackSubscribeRequest request;
    auto reader = stub->Subscribe(&context, request);
    v1::TrackList message;
    while (!stopRequested() && reader->Read(&message)) {
      PublishedTracks list;
      list.lidar_time_ns = message.lidar_time_ns();
      list.published_time_ns = message.published_time_ns();
      for (const auto& proto : message.tracks()) {
        auto track = fromProto(proto);
        if (track) list.tracks.push_back(std::move(*track));
      }
      times.push_back(sceneTimeOf(scene, schedule, rate_hz, list.lidar_time_ns));
      lists.push_back(std::move(list));
      if (scoringWindow(times, options.warmup_lists, options.scored_lists, options.scene_start_s)) break;
    }
    context.TryCancel();
    reader->Finish();
    if (scoringWindow(times, options.warmup_lists, options.scored_lists, options.scene_start_s)) return {};
  }
  return stopRequested() ? "stopped" : "the tracker published " + std::to_string(lists.size()) + " track lists in time";
}

}  // namespace

Expected<SceneTrackingRun> runSceneTracking(const std::filesystem::path& dir, const std::filesystem::path& scene_file,
                                            const sim::Scene& scene, const SceneTrackingOptions& options) {
  if (!tracksScene(scene)) return invalidArgument("the scene has nothing that moves or no camera: no tracks to score");
  if (options.scored_lists == 0) return invalidArgument("tracking: scored_lists must be positive");
  sim::SceneTopologyOptions layout;
  layout.base_port = options.base_port;
  layout.rate_hz = options.rate_hz;
  layout.tracker = true;
  layout.truth = options.truth;
  layout.tracking.association = options.association;
  layout.tracker_input = options.input;
  layout.displacement = options.displacement;
  layout.mapping = options.mapping;
  TopologyConfig topology = sim::sceneTopology(scene, scene_file, layout);
  topology.name = std::string("tracking-") + tracking::associationName(options.association) + "-" +
                  trackerInputName(options.input) + "-" + std::to_string(scene.lidars.size()) + "lidars";
  topology.period_ms = 1000.0 / options.rate_hz;
  if (options.free_ports) {
    try {
      useFreePorts(topology);
    } catch (const std::exception& e) {
      return Error{ErrorCode::kInternal, e.what()};
    }
  }
  const auto schedule = EpochSchedule::create(topology.period_ms, topology.deadline_ms);
  if (!schedule) return schedule.error();
  // Time for the window, and for a second one should the scene's cycle wrap inside the first.
  // From a given scene time on: up to one more cycle until the scene reaches it.
  const double wait_ms = options.scene_start_s ? scene.duration_s * 1000.0 : 0.0;
  const auto lists_time = std::chrono::milliseconds(static_cast<long>(
      2.0 * static_cast<double>(options.warmup_lists + options.scored_lists) * topology.period_ms + wait_ms));
  RunOptions run;
  run.frames = 1'000'000;   // keep every global map while the tracks are read
  run.complete_frames = 1;  // and stop once they are read
  run.timeout = std::chrono::seconds(40) + lists_time;
  SceneTrackingRun out;
  std::string ended;
  auto result = runCluster(dir, topology, run, [&](const Cluster&) {
    ended = readTracks(topology, scene, *schedule, options.rate_hz, options,
                       std::chrono::steady_clock::now() + std::chrono::seconds(20) + lists_time, out.lists);
  });
  if (!result) return result.error();
  if (!ended.empty()) {
    return Error{ErrorCode::kInternal, "tracking run: " + ended + "; see the logs in " + (dir / topology.name).string()};
  }
  out.topology = std::move(topology);
  out.result = std::move(*result);
  return out;
}

Expected<PublishedScores> scoreSceneTracking(const sim::Scene& scene, const SceneTrackingRun& run,
                                             const SceneTrackingOptions& options) {
  const auto schedule = EpochSchedule::create(run.topology.period_ms, run.topology.deadline_ms);
  if (!schedule) return schedule.error();
  return scorePublishedTracks(scene, *schedule, options.rate_hz, run.lists, options.warmup_lists, options.scored_lists,
                              tracking::MotConfig{options.match_distance_m}, options.scene_start_s);
}

Expected<std::string> sceneTrackListsJsonLines(const sim::Scene& scene, const SceneTrackingRun& run, const PublishedScores& scores,
                                               const SceneTrackingOptions& options) {
  const auto schedule = EpochSchedule::create(run.topology.period_ms, run.topology.deadline_ms);
  if (!schedule) return schedule.error();
  const auto heading = [](const std::optional<double>& rad) { return rad ? jsonNumber(*rad / kDegToRad) : Json(nullptr); };
  std::string out;
  const std::size_t end = std::min(run.lists.size(), scores.first_list + scores.frames);
  for (std::size_t i = scores.first_list; i < end; ++i) {
    const double time_s = sceneTimeOf(scene, *schedule, options.rate_hz, run.lists[i].lidar_time_ns);
    const TrackingFrame frame = trackingFrame(scene, time_s, run.lists[i].tracks);
    Json line;
    line["list"] = i;
    line["scene_time_s"] = jsonNumber(time_s);
    Json truth = Json::array();
    for (std::size_t k = 0; k < frame.mot.truth.size(); ++k) {
      const auto& o = frame.mot.truth[k];
      truth.push_back({{"id", o.id}, {"label", frame.truth_labels[k]}, {"x", jsonNumber(o.position.x())},
                       {"y", jsonNumber(o.position.y())}, {"heading_deg", heading(o.heading_rad)}});
    }
    Json tracks = Json::array();
    for (std::size_t k = 0; k < frame.mot.hypotheses.size(); ++k) {
      const auto& h = frame.mot.hypotheses[k];
      const bool confirmed = std::find(frame.confirmed.begin(), frame.confirmed.end(), static_cast<std::uint64_t>(h.id)) !=
                             frame.confirmed.end();
      tracks.push_back({{"id", h.id}, {"label", frame.hypothesis_labels[k]}, {"confirmed", confirmed},
                        {"x", jsonNumber(h.position.x())}, {"y", jsonNumber(h.position.y())}, {"heading_deg", heading(h.heading_rad)}});
    }
    line["truth"] = std::move(truth);
    line["tracks"] = std::move(tracks);
    out += line.dump() + "\n";
  }
  return out;
}

namespace {

Json motReport(const tracking::MotReport& r) {
  const auto& c = r.clear;
  Json j;
  j["mota"] = jsonNumber(c.mota);
  j["motp_m"] = jsonNumber(c.motp_m);
  j["id_switches"] = c.id_switches;
  j["fragmentations"] = c.fragmentations;
  j["idf1"] = jsonNumber(r.identity.idf1);
  j["matches"] = c.matches;
  j["misses"] = c.misses;
  j["false_positives"] = c.false_positives;
  j["loc_error_mean_m"] = jsonNumber(r.localization.mean_m);
  j["loc_error_p95_m"] = jsonNumber(r.localization.p95_m);
  j["loc_error_max_m"] = jsonNumber(r.localization.max_m);
  // Vehicles: the angle between the truth's heading and the track's, over the matches where the
  // track has one (people have none: the keys are left out).
  if (r.heading_error_deg.count > 0) {
    j["yaw_matches"] = r.heading_error_deg.count;
    j["yaw_error_mean_deg"] = jsonNumber(r.heading_error_deg.mean_m);
    j["yaw_error_max_deg"] = jsonNumber(r.heading_error_deg.max_m);
  }
  return j;
}

}  // namespace

std::string sceneTrackingText(const PublishedScores& s, const SceneTrackingOptions& o, std::size_t moving_objects) {
  const auto& mot = s.scores.mot;
  const auto& c = mot.clear;
  std::ostringstream out;
  out << "  tracking (" << tracking::associationName(o.association) << " on " << trackerInputName(o.input) << ", "
      << fixedText(100.0 * o.truth.miss_rate, 0) << " % of detections missed): " << s.frames << " track lists, scene time "
      << fixedText(s.first_time_s, 1) << " to "
      << fixedText(s.last_time_s, 1) << " s, against " << moving_objects << " moving objects (" << fixedText(o.match_distance_m, 1)
      << " m gate)\n"
      << "    MOTA " << fixedText(c.mota, 3) << "   MOTP " << fixedText(c.motp_m, 3) << " m   ID switches " << c.id_switches
      << "   fragmentations " << c.fragmentations << "   IDF1 " << fixedText(mot.identity.idf1, 3) << "\n"
      << "    localization error mean / p95 / max " << fixedText(mot.localization.mean_m, 3) << " / "
      << fixedText(mot.localization.p95_m, 3) << " / " << fixedText(mot.localization.max_m, 3) << " m   misses " << c.misses
      << "   false positives " << c.false_positives << "   tracks confirmed " << s.scores.tracks_confirmed << "\n";
  for (const auto& [label, r] : s.scores.by_label) {
    out << "    " << label << ": MOTA " << fixedText(r.clear.mota, 3) << ", ID switches " << r.clear.id_switches << ", IDF1 "
        << fixedText(r.identity.idf1, 3) << ", error mean " << fixedText(r.localization.mean_m, 3) << " m";
    if (r.heading_error_deg.count > 0) {
      out << ", yaw error mean " << fixedText(r.heading_error_deg.mean_m, 1) << " deg (max " << fixedText(r.heading_error_deg.max_m, 1)
          << ", " << r.heading_error_deg.count << " matches)";
    }
    out << " (tracks labelled " << label << " only)\n";
  }
  out << "    sensor time to published tracks: p50 " << fixedText(s.latency_p50_ms, 1) << " ms   p95 " << fixedText(s.latency_p95_ms, 1)
      << " ms   max " << fixedText(s.latency_max_ms, 1) << " ms\n";
  return out.str();
}

Json sceneTrackingReport(const PublishedScores& s, const SceneTrackingOptions& o, std::size_t moving_objects) {
  const auto& mot = s.scores.mot;
  const auto& c = mot.clear;
  Json j;
  j["association"] = tracking::associationName(o.association);
  j["tracker_input"] = trackerInputName(o.input);
  j["miss_rate"] = jsonNumber(o.truth.miss_rate);
  j["box_jitter_px"] = jsonNumber(o.truth.box_jitter_px);
  j["camera_latency_ms"] = jsonNumber(o.truth.latency_ms);
  j["moving_objects"] = moving_objects;
  j["frames"] = s.frames;
  j["scene_time_first_s"] = jsonNumber(s.first_time_s);
  j["scene_time_last_s"] = jsonNumber(s.last_time_s);
  j["match_distance_m"] = jsonNumber(o.match_distance_m);
  j["mota"] = jsonNumber(c.mota);
  j["motp_m"] = jsonNumber(c.motp_m);
  j["id_switches"] = c.id_switches;
  j["fragmentations"] = c.fragmentations;
  j["idf1"] = jsonNumber(mot.identity.idf1);
  j["loc_error_mean_m"] = jsonNumber(mot.localization.mean_m);
  j["loc_error_p95_m"] = jsonNumber(mot.localization.p95_m);
  j["loc_error_max_m"] = jsonNumber(mot.localization.max_m);
  j["tracks_confirmed"] = s.scores.tracks_confirmed;
  j["matches"] = c.matches;
  j["misses"] = c.misses;
  j["false_positives"] = c.false_positives;
  j["truth_count"] = c.truth_count;
  j["e2e_p50_ms"] = jsonNumber(s.latency_p50_ms);
  j["e2e_p95_ms"] = jsonNumber(s.latency_p95_ms);
  j["e2e_max_ms"] = jsonNumber(s.latency_max_ms);
  if (mot.heading_error_deg.count > 0) {
    j["yaw_matches"] = mot.heading_error_deg.count;
    j["yaw_error_mean_deg"] = jsonNumber(mot.heading_error_deg.mean_m);
  }
  // People within kNearRangeM of a LiDAR: how far their tracks are placed from them.
  if (s.scores.people_near && s.scores.people_near->clear.matches > 0) {
    j["people_near_range_m"] = jsonNumber(kNearRangeM);
    j["people_near_matches"] = s.scores.people_near->clear.matches;
    j["people_near_loc_error_mean_m"] = jsonNumber(s.scores.people_near->localization.mean_m);
  }
  // Per class: the truth of that class against the tracks labelled with it.
  j["per_class"] = Json::object();
  for (const auto& [label, report] : s.scores.by_label) j["per_class"][label] = motReport(report);
  return j;
}

std::string sceneTrackingJson(const PublishedScores& s, const SceneTrackingOptions& o, std::size_t moving_objects) {
  return jsonText(sceneTrackingReport(s, o, moving_objects));
}

}  // namespace fogmap::harness
