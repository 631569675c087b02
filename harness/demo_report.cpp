#include "harness/demo_report.hpp"

#include <algorithm>
#include <cstdio>
#include <numeric>

#include "common/base/clock.hpp"
#include "harness/object_breakdown.hpp"
#include "services/edge_cluster/scan_source.hpp"

namespace fogmap::harness {
namespace {

double mean(const std::vector<double>& v) {
  return v.empty() ? 0.0 : std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
}

double ratio(double num, double den) { return num / std::max(1.0, den); }

// The ellipsoids' bytes, and what their views (boxes, classes) add beside them, as lines whose
// labels are `width` wide.
std::string mapWireText(const MapWireCost& c, int width) {
  std::string out = formatText("  %-*s%.1f B each in the edges' map uploads (%.1f B were they sent as float32)\n", width,
                               "ellipsoids on the wire:", c.bytesPerEllipsoid(), c.exactBytesPerEllipsoid());
  if (c.views == 0) return out;
  out += formatText("  %-*s%.1f B an ellipsoid more: %.0f %% of them carry one, %.1f B each\n", width,
                    "their boxes and classes:", c.viewBytesPerEllipsoid(), 100.0 * c.viewShare(),
                    static_cast<double>(c.view_bytes) / static_cast<double>(c.views));
  return out;
}

// What the ellipsoids' views add to the edges' bytes per frame (over the frames scored against the
// truth, as madc_bytes_per_frame).
double viewBytesPerFrame(const SceneScores& s) { return s.madc_wire.viewBytesPerFrame(s.frames); }

void addMapWire(Json& j, const MapWireCost& c) {
  j["bytes_per_ellipsoid"] = jsonNumber(c.bytesPerEllipsoid());
  j["bytes_per_ellipsoid_exact_wire"] = jsonNumber(c.exactBytesPerEllipsoid());
  j["view_bytes_per_ellipsoid"] = jsonNumber(c.viewBytesPerEllipsoid());
  j["ellipsoids_with_views"] = jsonNumber(c.viewShare());
}

}  // namespace

EpochPairing pairEpochsByScan(const std::map<std::uint64_t, GlobalMapMessage>& madc,
                              const std::map<std::uint64_t, GlobalMapMessage>& baseline, std::size_t scans) {
  EpochPairing pairing;
  if (scans == 0) return pairing;
  std::map<std::size_t, std::uint64_t> baseline_by_scan;  // the first complete baseline epoch of each scan
  for (const auto& [e, g] : baseline) {
    if (completeEpoch(g)) baseline_by_scan.emplace(e % scans, e);
  }
  for (const auto& [e, g] : madc) {
    if (!completeEpoch(g)) {
      ++pairing.incomplete;
    } else if (const auto it = baseline_by_scan.find(e % scans); it != baseline_by_scan.end()) {
      pairing.compared.emplace_back(e, it->second);
    }
  }
  return pairing;
}

Expected<RecordedScores> scoreRecordedRuns(const TopologyConfig& madc_topology, const RunResult& madc,
                                           const RunResult& baseline) {
  const NodeConfig* sensing = nullptr;
  for (const auto& n : madc_topology.nodes) {
    if (n.sensor) sensing = &n;
  }
  if (sensing == nullptr) return invalidArgument("the topology " + madc_topology.name + " has no sensor");
  const auto source = ScanSource::open(*sensing->sensor);
  if (!source) return source.error();
  const std::size_t scans = source->files().size();

  const EpochPairing pairing = pairEpochsByScan(madc.epochs, baseline.epochs, scans);
  if (pairing.compared.empty()) {
    return Error{ErrorCode::kInternal, "no complete epoch of the same scan from both clusters"};
  }
  std::vector<std::uint64_t> compared;
  for (const auto& [e, b] : pairing.compared) compared.push_back(e);
  auto views = recomputeEdges(madc_topology, compared);
  if (!views) return views.error();

  RecordedScores s;
  s.published = madc.epochs.size();
  s.incomplete = pairing.incomplete;
  s.latencies = epochLatencies(madc.epochs);
  s.madc_bytes_per_frame = madc.bytes_moved / static_cast<double>(std::max<std::size_t>(madc.epochs.size(), 1));
  s.baseline_bytes_per_frame = baseline.bytes_moved / static_cast<double>(std::max<std::size_t>(baseline.epochs.size(), 1));
  std::vector<double> ri;
  std::vector<double> ari;
  std::vector<double> ri_points;
  for (const auto& [e, b] : pairing.compared) {
    const GlobalMapMessage& m = madc.epochs.at(e);
    const GlobalMapMessage& base = baseline.epochs.at(b);
    const EdgeView& view = views->at(e);
    RecordedEpoch row;
    row.epoch = e;
    row.scan = static_cast<std::size_t>(e % scans);
    row.objects = m.map.objects.size();
    row.baseline_objects = base.map.objects.size();
    row.madc_bytes = view.madc_bytes;
    row.baseline_bytes = view.baseline_bytes;
    row.merge_ms = m.merge_seconds * 1e3;
    row.e2e_ms = nsToMs(m.published_time_ns - m.header.sensor_time_ns);
    row.accuracy = accuracy(m, base, view);
    s.wire.add(view);
    if (row.accuracy.ok) {
      ri.push_back(row.accuracy.clusters.rand_index);
      ari.push_back(row.accuracy.clusters.adjusted_rand_index);
      ri_points.push_back(row.accuracy.points.rand_index);
    }
    s.epochs.push_back(std::move(row));
  }
  s.rand_index = mean(ri);
  s.adjusted_rand_index = mean(ari);
  s.rand_index_points = mean(ri_points);
  s.last_view = std::move(views->at(pairing.compared.back().first));
  return s;
}

std::string recordedScoresText(const RecordedScores& s) {
  std::string out = formatText("\n%12s %5s %8s %8s %12s %14s %8s %9s %9s %8s %8s\n", "epoch", "scan", "objects", "baseline",
                           "bytes MAD-C", "bytes baseline", "ratio", "merge ms", "e2e ms", "RI", "ARI");
  for (const RecordedEpoch& r : s.epochs) {
    const Accuracy& a = r.accuracy;
    out += formatText("%12lu %5zu %8zu %8zu %12zu %14zu %7.0fx %9.3f %9.1f %8.4f %8.4f%s\n", static_cast<unsigned long>(r.epoch),
                  r.scan, r.objects, r.baseline_objects, r.madc_bytes, r.baseline_bytes,
                  static_cast<double>(r.baseline_bytes) / static_cast<double>(std::max<std::size_t>(r.madc_bytes, 1)), r.merge_ms,
                  r.e2e_ms, a.ok ? a.clusters.rand_index : 0.0, a.ok ? a.clusters.adjusted_rand_index : 0.0,
                  a.ok ? "" : ("  (" + a.problem + ")").c_str());
  }
  const EpochLatencies& l = s.latencies;
  out += formatText("\n%zu epochs published by MAD-C (%zu incomplete: a node missing; %zu without a sensor time: every node "
                "missing, no end-to-end latency), %zu compared with the baseline%s\n",
                s.published, s.incomplete, l.without_sensor_time, s.epochs.size(), l.incomplete_list.c_str());
  out += formatText("  bytes per frame, all links:  MAD-C %.0f B   baseline %.0f B   ratio %.0fx\n", s.madc_bytes_per_frame,
                s.baseline_bytes_per_frame, ratio(s.baseline_bytes_per_frame, s.madc_bytes_per_frame));
  out += mapWireText(s.wire, 29);
  out += formatText("  merge latency at the sink:   p50 %.3f ms   p99 %.3f ms\n", percentile(l.merge_ms, 0.5),
                percentile(l.merge_ms, 0.99));
  out += formatText("  end-to-end latency:          p50 %.1f ms   p99 %.1f ms   (sensor timestamp to global map, complete epochs)\n",
                percentile(l.e2e_ms, 0.5), percentile(l.e2e_ms, 0.99));
  out += formatText("                               p50 %.1f ms   p99 %.1f ms   (every epoch with a sensor time, start-up included)\n",
                percentile(l.e2e_all_ms, 0.5), percentile(l.e2e_all_ms, 0.99));
  out += formatText("  accuracy vs baseline:        Rand index %.4f   adjusted %.4f   (local clusters); Rand index %.4f (points)\n",
                s.rand_index, s.adjusted_rand_index, s.rand_index_points);
  return out;
}

Json recordedReport(const RecordedScores& s) {
  const EpochLatencies& l = s.latencies;
  Json j;
  j["frames"] = s.epochs.size();
  j["epochs_published"] = s.published;
  j["bytes_madc_per_frame"] = jsonNumber(s.madc_bytes_per_frame);
  j["bytes_baseline_per_frame"] = jsonNumber(s.baseline_bytes_per_frame);
  j["bytes_ratio"] = jsonNumber(ratio(s.baseline_bytes_per_frame, s.madc_bytes_per_frame));
  addMapWire(j, s.wire);
  j["rand_index_mean"] = jsonNumber(s.rand_index);
  j["ari_mean"] = jsonNumber(s.adjusted_rand_index);
  j["rand_index_points_mean"] = jsonNumber(s.rand_index_points);
  j["e2e_p50_ms"] = jsonNumber(percentile(l.e2e_ms, 0.5));
  j["e2e_p99_ms"] = jsonNumber(percentile(l.e2e_ms, 0.99));
  j["e2e_all_epochs_p99_ms"] = jsonNumber(percentile(l.e2e_all_ms, 0.99));
  j["epochs_incomplete"] = s.incomplete;
  j["epochs_without_sensor_time"] = l.without_sensor_time;
  j["merge_p50_ms"] = jsonNumber(percentile(l.merge_ms, 0.5));
  j["merge_p99_ms"] = jsonNumber(percentile(l.merge_ms, 0.99));
  return j;
}

std::string sceneScoresText(const SceneScores& s) {
  std::string out = formatText("\n%zu complete frames scored against the truth, %zu against the baseline\n", s.frames,
                           s.frames_vs_baseline);
  out += formatText("  bytes per frame, edge uploads: MAD-C %.0f B   baseline %.0f B   ratio %.0fx   (raw scans %.0f B: %.0fx)\n",
                s.madc_bytes_per_frame, s.baseline_bytes_per_frame, ratio(s.baseline_bytes_per_frame, s.madc_bytes_per_frame),
                s.raw_bytes_per_frame, ratio(s.raw_bytes_per_frame, s.madc_bytes_per_frame));
  const double views_per_frame = viewBytesPerFrame(s);
  if (views_per_frame > 0.0) {
    const double bare = s.madc_bytes_per_frame - views_per_frame;
    out += formatText("                                 of which views %.0f B; without them %.0f B: %.0fx the baseline, %.0fx the raw scans\n",
                      views_per_frame, bare, ratio(s.baseline_bytes_per_frame, bare), ratio(s.raw_bytes_per_frame, bare));
  }
  out += mapWireText(s.madc_wire, 31);
  out += formatText("  MAD-C vs baseline:             Rand index %.4f   adjusted %.4f (local clusters); points %.4f / %.4f\n",
                s.madc_vs_baseline.rand_index, s.madc_vs_baseline.adjusted_rand_index, s.ext_vs_baseline.rand_index,
                s.ext_vs_baseline.adjusted_rand_index);
  out += formatText("  against the truth (points):    MAD-C-ext RI %.4f ARI %.4f   baseline RI %.4f ARI %.4f\n",
                s.madc_vs_truth.rand_index, s.madc_vs_truth.adjusted_rand_index, s.baseline_vs_truth.rand_index,
                s.baseline_vs_truth.adjusted_rand_index);
  out += formatText("  true objects (all frames):     %zu: found whole %zu, split %zu, merged %zu, missed %zu (MAD-C)\n",
                s.madc_objects.objects_true, s.madc_objects.found_whole, s.madc_objects.split, s.madc_objects.merged,
                s.madc_objects.missed);
  out += formatText("                                 %zu: found whole %zu, split %zu, merged %zu, missed %zu (baseline)\n",
                s.baseline_objects.objects_true, s.baseline_objects.found_whole, s.baseline_objects.split,
                s.baseline_objects.merged, s.baseline_objects.missed);
  out += objectBreakdownText(s.madc_breakdown, s.baseline_breakdown);
  out += formatText("  times: local clustering %.2f ms per scan, MERGE %.3f ms per epoch; baseline central clustering %.2f ms\n",
                s.clustering_ms, s.merge_ms, s.baseline_clustering_ms);
  out += formatText("  end-to-end p50: MAD-C %.1f ms   baseline %.1f ms\n", s.madc_e2e_p50_ms, s.baseline_e2e_p50_ms);
  return out;
}

Json sceneScoresReport(const SceneScores& s) {
  Json j;
  j["frames"] = s.frames;
  j["frames_vs_baseline"] = s.frames_vs_baseline;
  j["bytes_madc_per_frame"] = jsonNumber(s.madc_bytes_per_frame);
  j["bytes_baseline_per_frame"] = jsonNumber(s.baseline_bytes_per_frame);
  j["bytes_ratio"] = jsonNumber(ratio(s.baseline_bytes_per_frame, s.madc_bytes_per_frame));
  j["bytes_raw_per_frame"] = jsonNumber(s.raw_bytes_per_frame);
  j["bytes_views_per_frame"] = jsonNumber(viewBytesPerFrame(s));
  addMapWire(j, s.madc_wire);
  j["rand_index_mean"] = jsonNumber(s.madc_vs_baseline.rand_index);
  j["ari_mean"] = jsonNumber(s.madc_vs_baseline.adjusted_rand_index);
  j["rand_index_points_mean"] = jsonNumber(s.ext_vs_baseline.rand_index);
  j["rand_index_truth_mean"] = jsonNumber(s.madc_vs_truth.rand_index);
  j["ari_truth_mean"] = jsonNumber(s.madc_vs_truth.adjusted_rand_index);
  j["baseline_rand_index_truth_mean"] = jsonNumber(s.baseline_vs_truth.rand_index);
  j["baseline_ari_truth_mean"] = jsonNumber(s.baseline_vs_truth.adjusted_rand_index);
  j["objects_true"] = s.madc_objects.objects_true;
  j["objects_found_whole"] = s.madc_objects.found_whole;
  j["objects_split"] = s.madc_objects.split;
  j["objects_merged"] = s.madc_objects.merged;
  j["objects_missed"] = s.madc_objects.missed;
  j["baseline_objects_found_whole"] = s.baseline_objects.found_whole;
  j["baseline_objects_split"] = s.baseline_objects.split;
  j["baseline_objects_merged"] = s.baseline_objects.merged;
  j["baseline_objects_missed"] = s.baseline_objects.missed;
  j["by_range_band"] = rangeBandReport(s.madc_breakdown, s.baseline_breakdown);
  j["by_kind"] = kindReport(s.madc_breakdown, s.baseline_breakdown);
  j["clustering_ms"] = jsonNumber(s.clustering_ms);
  j["merge_ms"] = jsonNumber(s.merge_ms);
  j["baseline_clustering_ms"] = jsonNumber(s.baseline_clustering_ms);
  j["e2e_p50_ms"] = jsonNumber(s.madc_e2e_p50_ms);
  j["baseline_e2e_p50_ms"] = jsonNumber(s.baseline_e2e_p50_ms);
  return j;
}

}  // namespace fogmap::harness
