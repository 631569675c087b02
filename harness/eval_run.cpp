#include "harness/eval_run.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "common/sim/generators.hpp"
#include "harness/evaluation.hpp"
#include "harness/object_breakdown.hpp"
#include "harness/report_text.hpp"
#include "harness/shaped_links.hpp"

namespace fogmap::harness {
namespace {

constexpr double kRateHz = 10.0;

std::string sceneLabel(int objects, int lidars) {
  return std::to_string(objects) + " objects, " + std::to_string(lidars) + " LiDARs";
}

}  // namespace

EvalPlan quickEvalPlan() {
  EvalPlan plan;
  plan.quick = true;
  plan.lidar_counts = {2, 3};
  plan.object_counts = {10, 30};
  plan.accuracy_objects = 30;
  plan.alphas = {0.8, 1.5, 2.4};
  plan.frames = 4;
  plan.link_lidars = 3;
  plan.link_objects = 100;
  // 4 people and a car for 6 s: every association and miss rate in about a second.
  plan.tracking->people = 4;
  plan.tracking->vehicles = 1;
  plan.tracking->frames = 60;
  plan.tracking->seed = 7;
  plan.out = ".fogmap/eval-quick";
  plan.work = ".fogmap/eval-quick/work";
  return plan;
}

Expected<EvalResult> runEvaluation(const EvalPlan& plan, const std::function<void(const std::string&)>& log) {
  if (plan.lidar_counts.empty() || plan.object_counts.empty()) return invalidArgument("eval: no LiDAR counts or scene sizes");
  if (std::find(plan.object_counts.begin(), plan.object_counts.end(), plan.accuracy_objects) == plan.object_counts.end()) {
    return invalidArgument("eval: the alpha sweep's scene size (" + std::to_string(plan.accuracy_objects) +
                           " objects) must be one of the scene sizes");
  }
  if (plan.frames == 0) return invalidArgument("eval: frames must be positive");
  std::vector<double> precision_alphas = plan.precision_alphas;
  if (precision_alphas.empty()) {
    for (int k = 1; k <= 15; ++k) precision_alphas.push_back(0.2 * k);
  }
  const auto start = std::chrono::steady_clock::now();
  EvalResult result;
  const std::filesystem::path runs = plan.work / "runs";
  SceneRunOptions options;
  options.free_ports = true;
  options.frames = plan.frames;
  options.rate_hz = kRateHz;
  const auto stamp = [&] {
    return fixedText(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 1) + " s";
  };

  for (const int objects : plan.object_counts) {
    for (const int lidars : plan.lidar_counts) {
      sim::Scene scene = sim::randomScene(objects, lidars, plan.seed);
      const auto dir = runs / ("objects-" + std::to_string(objects) + "-lidars-" + std::to_string(lidars));
      const auto file = writeCycledScene(dir, scene, plan.frames, kRateHz);
      if (!file) return file.error();
      options.mode = Mode::kBaseline;
      options.alpha = kPaperAlpha;
      auto baseline = runScene(dir, *file, scene, options);
      if (!baseline) return Error{baseline.error().code, sceneLabel(objects, lidars) + ", baseline: " + baseline.error().message};
      options.mode = Mode::kExt;
      auto madc = runScene(dir, *file, scene, options);
      if (!madc) return Error{madc.error().code, sceneLabel(objects, lidars) + ", MAD-C: " + madc.error().message};
      auto scores = scoreSceneRuns(scene, *madc, &*baseline);
      if (!scores) return Error{scores.error().code, sceneLabel(objects, lidars) + ": " + scores.error().message};
      result.sizes.push_back({objects, lidars, *scores});
      log("[" + stamp() + "] " + sceneLabel(objects, lidars) + ": bytes " + fixedText(scores->madc_bytes_per_frame, 0) + " / " +
          fixedText(scores->baseline_bytes_per_frame, 0) + ", RI vs baseline " + fixedText(scores->madc_vs_baseline.rand_index, 4) +
          ", ARI vs truth " + fixedText(scores->madc_vs_truth.adjusted_rand_index, 4) + " (baseline " +
          fixedText(scores->baseline_vs_truth.adjusted_rand_index, 4) + ")");
      if (objects != plan.accuracy_objects) continue;

      // A picture of the scenario: MAD-C's global map of its last complete frame over the truth
      // (drawn by pictures/eval_figures from what is kept here).
      if (auto last = lastCompleteView(*madc)) {
        result.pictures.push_back({"birdseye_" + std::to_string(objects) + "_objects_" + std::to_string(lidars) + "_lidars.png",
                                   sceneLabel(objects, lidars) + ", alpha 1.5: MAD-C's global objects (ellipses, "
                                   "one colour per object) over the true outlines",
                                   "MAD-C, " + sceneLabel(objects, lidars), madc->result.epochs.at(last->first),
                                   std::move(last->second), scene, madc->topology});
      }
      // Fig. 6: the ellipsoids of these very frames at every alpha, with and without the aura.
      auto views = recomputeEdges(madc->topology, completeEpochs(madc->result));
      if (!views) return views.error();
      for (const double alpha : precision_alphas) {
        for (const bool aura : {false, true}) {
          const EllipsoidParams params{alpha, aura ? madc->topology.madc.clustering.eps_m / 2.0 : 0.0};
          double precision = 0.0;
          double recall = 0.0;
          std::size_t clusters = 0;
          for (const auto& [e, view] : *views) {
            const PrecisionRecall pr = ellipsoidPrecisionRecall(view, params);
            precision += pr.precision * static_cast<double>(pr.clusters);
            recall += pr.recall * static_cast<double>(pr.clusters);
            clusters += pr.clusters;
          }
          if (clusters > 0) {
            result.precision.push_back({lidars, alpha, aura, precision / static_cast<double>(clusters),
                                        recall / static_cast<double>(clusters), clusters});
          }
        }
      }
      // Figs. 7 and 8: the services at every alpha, against the same baseline and the truth.
      for (const double alpha : plan.alphas) {
        if (alpha == kPaperAlpha) {
          result.alphas.push_back({lidars, alpha, *scores});
          continue;
        }
        options.alpha = alpha;
        auto run = runScene(dir, *file, scene, options);
        if (!run) return Error{run.error().code, sceneLabel(objects, lidars) + ", alpha " + fixedText(alpha, 2) + ": " + run.error().message};
        auto swept = scoreSceneRuns(scene, *run, &*baseline);
        if (!swept) return swept.error();
        result.alphas.push_back({lidars, alpha, *swept});
        log("[" + stamp() + "]   alpha " + fixedText(alpha, 2) + ": RI vs baseline " + fixedText(swept->madc_vs_baseline.rand_index, 4) +
            ", ARI vs truth " + fixedText(swept->madc_vs_truth.adjusted_rand_index, 4));
      }
    }
  }
  std::stable_sort(result.alphas.begin(), result.alphas.end(), [](const AlphaRow& a, const AlphaRow& b) {
    return a.lidars != b.lidars ? a.lidars < b.lidars : a.alpha < b.alpha;
  });

  // Fig. 9 (right) and Table 2: every edge behind a link of link_mbit.
  LinkResult& links = result.links;
  links.lidars = plan.link_lidars;
  links.objects = plan.link_objects;
  links.rate_hz = plan.link_rate_hz;
  if (!plan.link_mbit) {
    links.skipped = "not asked for (--no-links)";
  } else if (Status possible = shapingAvailable(); !possible) {
    links.skipped = possible.error().message;
  } else {
    links.mbit = *plan.link_mbit;
    sim::Scene scene = sim::randomScene(plan.link_objects, plan.link_lidars, plan.seed);
    const auto dir = runs / ("links-" + std::to_string(plan.link_lidars) + "-lidars");
    const auto file = writeCycledScene(dir, scene, plan.frames, plan.link_rate_hz);
    if (!file) return file.error();
    SceneRunOptions shaped = options;
    shaped.rate_hz = plan.link_rate_hz;
    shaped.link_mbit = plan.link_mbit;
    shaped.alpha = kPaperAlpha;
    shaped.mode = Mode::kBaseline;
    auto baseline = runScene(dir, *file, scene, shaped);
    if (!baseline) return Error{baseline.error().code, "shaped links, baseline: " + baseline.error().message};
    shaped.baseline_raw = true;
    auto raw = runScene(dir, *file, scene, shaped);
    if (!raw) return Error{raw.error().code, "shaped links, baseline shipping whole scans: " + raw.error().message};
    shaped.baseline_raw = false;
    links.raw_baseline_e2e_p50_ms = endToEndP50Ms(*raw);
    // The root's time on the complete frames (its histogram also holds the empty start-up epochs).
    double root_seconds = 0.0;
    std::size_t complete_frames = 0;
    for (const auto e : completeEpochs(raw->result)) {
      root_seconds += raw->result.epochs.at(e).merge_seconds;
      ++complete_frames;
    }
    if (complete_frames > 0) links.raw_baseline_merge_ms = root_seconds / static_cast<double>(complete_frames) * 1e3;
    // Plain MAD-C: the ellipsoids alone cross the links (ext would ship the points beside them).
    shaped.mode = Mode::kMadc;
    auto madc = runScene(dir, *file, scene, shaped);
    if (!madc) return Error{madc.error().code, "shaped links, MAD-C: " + madc.error().message};
    auto scores = scoreSceneRuns(scene, *madc, &*baseline);
    if (!scores) return scores.error();
    links.scores = *scores;
    links.ran = true;
    log("[" + stamp() + "] " + sceneLabel(plan.link_objects, plan.link_lidars) + " behind " + fixedText(links.mbit, 0) +
        " Mbit/s links: end to end p50 " + fixedText(scores->madc_e2e_p50_ms, 1) + " ms MAD-C, " +
        fixedText(scores->baseline_e2e_p50_ms, 1) + " ms baseline, " + fixedText(links.raw_baseline_e2e_p50_ms, 1) +
        " ms baseline shipping whole scans");
  }
  if (!links.ran) log("[" + stamp() + "] SKIPPED the limited links (Fig. 9): " + links.skipped);

  // Tracking: the fusion paper's association against fogmap's, in process on one moving scene.
  if (plan.tracking) {
    auto tracking = runTrackingEval(*plan.tracking);
    if (!tracking) return Error{tracking.error().code, "tracking: " + tracking.error().message};
    for (const TrackingRun& run : tracking->runs) {
      log("[" + stamp() + "] tracking " + run.association + ", " + fixedText(100.0 * run.miss_rate, 0) + " % missed: MOTA " +
          fixedText(run.mot.clear.mota, 3) + ", IDF1 " + fixedText(run.mot.identity.idf1, 3) + ", " +
          std::to_string(run.mot.clear.id_switches) + " ID switches");
    }
    result.tracking = std::move(tracking).value();
  }
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

namespace {

std::string accuracyCsv(const EvalResult& r) {
  std::ostringstream out;
  out << "lidars,alpha,frames,ri_madc_vs_baseline,ari_madc_vs_baseline,ri_ext_vs_baseline,ari_ext_vs_baseline,"
         "ri_madc_vs_truth,ari_madc_vs_truth,ri_baseline_vs_truth,ari_baseline_vs_truth,objects_true,found_whole,split,merged,missed\n";
  for (const auto& a : r.alphas) {
    const SceneScores& s = a.scores;
    out << a.lidars << ',' << a.alpha << ',' << s.frames << ',' << s.madc_vs_baseline.rand_index << ','
        << s.madc_vs_baseline.adjusted_rand_index << ',' << s.ext_vs_baseline.rand_index << ','
        << s.ext_vs_baseline.adjusted_rand_index << ',' << s.madc_vs_truth.rand_index << ','
        << s.madc_vs_truth.adjusted_rand_index << ',' << s.baseline_vs_truth.rand_index << ','
        << s.baseline_vs_truth.adjusted_rand_index << ',' << s.madc_objects.objects_true << ',' << s.madc_objects.found_whole
        << ',' << s.madc_objects.split << ',' << s.madc_objects.merged << ',' << s.madc_objects.missed << '\n';
  }
  return out.str();
}

std::string precisionCsv(const EvalResult& r) {
  std::ostringstream out;
  out << "lidars,alpha,aura,precision,recall,clusters\n";
  for (const auto& p : r.precision) {
    out << p.lidars << ',' << p.alpha << ',' << (p.aura ? 1 : 0) << ',' << p.precision << ',' << p.recall << ',' << p.clusters << '\n';
  }
  return out.str();
}

std::string costsCsv(const EvalResult& r) {
  std::ostringstream out;
  out << "objects,lidars,bytes_madc_per_frame,bytes_baseline_per_frame,bytes_ratio,bytes_raw_per_frame,bytes_ratio_raw,pairs_tested,pairs_all,"
         "clustering_ms,merge_ms,baseline_clustering_ms,e2e_madc_p50_ms,e2e_baseline_p50_ms,ri_madc_vs_baseline,"
         "ari_madc_vs_truth,ari_baseline_vs_truth\n";
  for (const auto& z : r.sizes) {
    const SceneScores& s = z.scores;
    out << z.objects << ',' << z.lidars << ',' << s.madc_bytes_per_frame << ',' << s.baseline_bytes_per_frame << ','
        << s.baseline_bytes_per_frame / std::max(1.0, s.madc_bytes_per_frame) << ',' << s.raw_bytes_per_frame << ','
        << s.raw_bytes_per_frame / std::max(1.0, s.madc_bytes_per_frame) << ',' << s.pairs_tested_per_epoch << ','
        << s.pairs_all_per_epoch << ',' << s.clustering_ms << ',' << s.merge_ms << ',' << s.baseline_clustering_ms << ','
        << s.madc_e2e_p50_ms << ',' << s.baseline_e2e_p50_ms << ',' << s.madc_vs_baseline.rand_index << ','
        << s.madc_vs_truth.adjusted_rand_index << ',' << s.baseline_vs_truth.adjusted_rand_index << '\n';
  }
  return out.str();
}

std::string linksCsv(const EvalResult& r) {
  std::ostringstream out;
  out << "lidars,objects,mbit,rate_hz,e2e_madc_p50_ms,e2e_baseline_p50_ms,speedup,e2e_raw_baseline_p50_ms,speedup_raw,skipped\n";
  const LinkResult& l = r.links;
  out << l.lidars << ',' << l.objects << ',' << l.mbit << ',' << l.rate_hz << ',';
  if (l.ran) {
    out << l.scores.madc_e2e_p50_ms << ',' << l.scores.baseline_e2e_p50_ms << ','
        << l.scores.baseline_e2e_p50_ms / std::max(1e-9, l.scores.madc_e2e_p50_ms) << ',' << l.raw_baseline_e2e_p50_ms << ','
        << l.raw_baseline_e2e_p50_ms / std::max(1e-9, l.scores.madc_e2e_p50_ms) << ",\n";
  } else {
    out << ",,,,,\"" << l.skipped << "\"\n";
  }
  return out.str();
}

std::string trackingCsv(const TrackingEvalResult& t) {
  std::ostringstream out;
  out << "association,miss_rate,mota,motp_m,id_switches,fragmentations,idf1,loc_error_mean_m,loc_error_p95_m,loc_error_max_m,"
         "misses,false_positives,tracks_confirmed,step_mean_ms,step_max_ms\n";
  for (const TrackingRun& run : t.runs) {
    const auto& c = run.mot.clear;
    out << run.association << ',' << run.miss_rate << ',' << c.mota << ',' << c.motp_m << ',' << c.id_switches << ','
        << c.fragmentations << ',' << run.mot.identity.idf1 << ',' << run.mot.localization.mean_m << ','
        << run.mot.localization.p95_m << ',' << run.mot.localization.max_m << ',' << c.misses << ',' << c.false_positives << ','
        << run.tracks_confirmed << ',' << run.step_mean_ms << ',' << run.step_max_ms << '\n';
  }
  return out.str();
}

Json scoresReport(const SceneScores& s) {
  Json j;
  j["frames"] = s.frames;
  j["frames_vs_baseline"] = s.frames_vs_baseline;
  j["rand_index_vs_baseline"] = jsonNumber(s.madc_vs_baseline.rand_index);
  j["ari_vs_baseline"] = jsonNumber(s.madc_vs_baseline.adjusted_rand_index);
  j["rand_index_points_vs_baseline"] = jsonNumber(s.ext_vs_baseline.rand_index);
  j["rand_index_truth"] = jsonNumber(s.madc_vs_truth.rand_index);
  j["ari_truth"] = jsonNumber(s.madc_vs_truth.adjusted_rand_index);
  j["baseline_rand_index_truth"] = jsonNumber(s.baseline_vs_truth.rand_index);
  j["baseline_ari_truth"] = jsonNumber(s.baseline_vs_truth.adjusted_rand_index);
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
  j["bytes_madc_per_frame"] = jsonNumber(s.madc_bytes_per_frame);
  j["bytes_baseline_per_frame"] = jsonNumber(s.baseline_bytes_per_frame);
  j["bytes_raw_per_frame"] = jsonNumber(s.raw_bytes_per_frame);
  j["pairs_tested"] = jsonNumber(s.pairs_tested_per_epoch);
  j["pairs_all"] = jsonNumber(s.pairs_all_per_epoch);
  j["clustering_ms"] = jsonNumber(s.clustering_ms);
  j["merge_ms"] = jsonNumber(s.merge_ms);
  j["baseline_clustering_ms"] = jsonNumber(s.baseline_clustering_ms);
  j["e2e_madc_p50_ms"] = jsonNumber(s.madc_e2e_p50_ms);
  j["e2e_baseline_p50_ms"] = jsonNumber(s.baseline_e2e_p50_ms);
  return j;
}

std::string evalJson(const EvalPlan& plan, const EvalResult& r) {
  Json j;
  j["quick"] = plan.quick;
  j["seconds"] = jsonNumber(r.seconds);
  j["frames_per_run"] = plan.frames;
  j["seed"] = plan.seed;
  j["alpha_sweep"] = Json::array();
  for (const AlphaRow& a : r.alphas) {
    j["alpha_sweep"].push_back({{"objects", plan.accuracy_objects},
                                {"lidars", a.lidars},
                                {"alpha", jsonNumber(a.alpha)},
                                {"scores", scoresReport(a.scores)}});
  }
  j["scene_sizes"] = Json::array();
  for (const SizeRow& z : r.sizes) {
    j["scene_sizes"].push_back(
        {{"objects", z.objects}, {"lidars", z.lidars}, {"alpha", jsonNumber(kPaperAlpha)}, {"scores", scoresReport(z.scores)}});
  }
  j["precision_recall"] = Json::array();
  for (const PrecisionRow& p : r.precision) {
    j["precision_recall"].push_back({{"lidars", p.lidars},
                                     {"alpha", jsonNumber(p.alpha)},
                                     {"aura", p.aura},
                                     {"precision", jsonNumber(p.precision)},
                                     {"recall", jsonNumber(p.recall)},
                                     {"clusters", p.clusters}});
  }
  Json links;
  links["ran"] = r.links.ran;
  links["skipped"] = r.links.skipped;
  links["lidars"] = r.links.lidars;
  links["objects"] = r.links.objects;
  links["mbit"] = jsonNumber(r.links.mbit);
  links["rate_hz"] = jsonNumber(r.links.rate_hz);
  if (r.links.ran) {
    links["e2e_raw_baseline_p50_ms"] = jsonNumber(r.links.raw_baseline_e2e_p50_ms);
    links["raw_baseline_root_ms"] = jsonNumber(r.links.raw_baseline_merge_ms);
    links["scores"] = scoresReport(r.links.scores);
  }
  j["links"] = std::move(links);
  if (r.tracking) j["tracking"] = trackingReport(*r.tracking);
  return jsonText(j);
}

std::string relativeLink(const std::filesystem::path& file, const std::filesystem::path& from_dir) {
  return std::filesystem::relative(std::filesystem::absolute(file), std::filesystem::absolute(from_dir)).generic_string();
}

// The tracking section: the associations side by side, then every run in detail (trackingTableMarkdown).
std::string trackingSection(const TrackingEvalResult& t) {
  const TrackingEvalConfig& c = t.config;
  std::ostringstream md;
  const auto count = [](int n, const std::string& one, const std::string& many) {
    return std::to_string(n) + " " + (n == 1 ? one : many);
  };
  md << "## Tracking: the fusion paper's association against fogmap's\n\n"
     << "The tracker (common/tracking, the tracker service's core) in process on simulated moving scene " << t.scene << " ("
     << count(c.people, "person", "people") << " and " << count(c.vehicles, "car", "cars") << " crossing a 40 x 40 m area, "
     << count(t.lidars, "static VLP-16 LiDAR", "static VLP-16 LiDARs") << ", " << count(t.cameras, "camera", "cameras") << "; " << c.frames << " LiDAR frames at " << fixedText(c.rate_hz, 0) << " Hz, seed " << c.seed
     << "), through the whole chain: every LiDAR frame through ground removal and the displacement detector (the fusion "
     << "paper's Algorithm 1), the centroids of one instant merged across LiDARs, every camera's detections replayed from "
     << "the truth (occluded objects not reported, " << fixedText(c.box_jitter_px, 0) << " px box jitter, "
     << fixedText(c.camera_latency_ms, 0) << " ms latency) with the given share of them missed (seeded, the same for both), "
     << "and the tracker with either association on the same centroids and detections. `paper`: the paper's Algorithms "
     << "2-5 (greedy nearest neighbour, no motion model); `kalman`: a constant-velocity Kalman filter per track, Hungarian "
     << "assignment with a Mahalanobis gate, tentative/confirmed/lost tracks. Scored against the objects' true centres on "
     << "the ground: CLEAR MOT (a pair counts as a match closer than " << fixedText(c.match_distance_m, 1)
     << " m), IDF1 and the localization error over the matches; hypotheses are the confirmed and lost tracks. The same "
     << "run as `fogctl track-eval` (docs/tracking.md discusses it).\n\n"
     << "Each cell: paper / kalman. MOTP is the mean localization error over the matches.\n\n"
     << trackingComparisonMarkdown(t) << "\nEvery run:\n\n" << trackingTableMarkdown(t);
  return md.str();
}

std::string report(const EvalPlan& plan, const EvalResult& r, const std::filesystem::path& doc) {
  const auto image = [&](const std::string& name, const std::string& alt) {
    return "![" + alt + "](" + relativeLink(plan.out / name, doc.parent_path()) + ")\n";
  };
  std::ostringstream md;
  md << "# Evaluation: the MAD-C paper reproduced with the running services\n\n"
     << "Generated by `" << plan.command << "` in " << fixedText(r.seconds, 0) << " s"
     << (plan.quick ? " (the quick form: fewer LiDAR counts, scene sizes and alphas, a shorter tracking run)" : "")
     << ". Every number of the MAD-C sections comes from real clusters of local processes (edge-cluster per simulated "
     << "LiDAR, merge-aggregator as the sink) on random scenes made by "
     << "`fogctl scene random` (seed " << plan.seed << ", HDL-32E LiDARs at the paper's spots Lambda_2 .. Lambda_7, eps 0.35 m, "
     << "10 points): MAD-C (ext mode; plain MAD-C behind the limited links) as a scene's topology runs it by default "
     << "(each edge clustering sensor-aware with its LiDAR's beam table and shipping every cluster, fragments included, "
     << "each ellipsoid reaching its cluster's ends along its axes up to alpha_max 2.5: alpha is the floor of its semi-axes; "
     << "`--clustering exact --fragment-min-points off --alpha-max off` is the paper's MAD-C, compared in the README) and the baseline "
     << "(every pre-processed point shipped, clustered exactly at the sink) over the same " << plan.frames
     << " frames of each scene. Accuracy is scored against the baseline (as the paper does) and against the simulator's "
     << "per-point truth."
     << (r.tracking ? " The last section compares the camera-LiDAR fusion paper's association with fogmap's Kalman tracker "
                      "on a moving scene, against the simulator's truth."
                    : "")
     << " CSV files and `eval.json` beside the plots hold every figure.\n\n";

  md << "## Ellipsoid precision and recall against alpha (paper Fig. 6)\n\n"
     << "For each local cluster whose points are mostly of one true object: precision = the edge's points inside the cluster's "
     << "ellipsoid that belong to that object / all its points inside; recall = those points / the edge's points of the "
     << "object. The ellipsoids are those the edges build (same code, the frames the services processed), for alpha from "
     << "0.2 to 3.0, with the aura (eps/2) and without. The paper (KITTI) finds [0.8, 2.4] a good range.\n\n"
     << image("fig6_precision_recall.png", "precision and recall against alpha") << "\n";

  md << "## Accuracy (paper Figs. 7 and 8)\n\n"
     << "Scenes of " << plan.accuracy_objects << " objects. RI: Rand index, ARI: adjusted Rand index. Against the baseline the "
     << "elements are local clusters (MAD-C, as in the paper) or points (MAD-C-ext); against the truth they are points "
     << "(points of no true object, such as ground left after ground removal, count as singletons). The paper reports Rand "
     << "indices above 0.95 for every configuration.\n\n"
     << "| LiDARs | alpha | RI vs baseline | ARI vs baseline | RI points (ext) | RI vs truth | ARI vs truth | baseline ARI vs truth | true objects | whole | split | merged | missed |\n"
     << "|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& a : r.alphas) {
    const SceneScores& s = a.scores;
    md << "| " << a.lidars << " | " << fixedText(a.alpha, 1) << " | " << fixedText(s.madc_vs_baseline.rand_index, 4) << " | "
       << fixedText(s.madc_vs_baseline.adjusted_rand_index, 4) << " | " << fixedText(s.ext_vs_baseline.rand_index, 4) << " | "
       << fixedText(s.madc_vs_truth.rand_index, 4) << " | " << fixedText(s.madc_vs_truth.adjusted_rand_index, 4) << " | "
       << fixedText(s.baseline_vs_truth.adjusted_rand_index, 4) << " | " << s.madc_objects.objects_true << " | "
       << s.madc_objects.found_whole << " | " << s.madc_objects.split << " | " << s.madc_objects.merged << " | "
       << s.madc_objects.missed << " |\n";
  }
  md << "\nObject counts are summed over the frames (a true object counts once per frame in which it has at least 10 "
     << "points).\n\n"
     << image("fig7_rand_index.png", "Rand index against the baseline") << "\n"
     << image("fig8_ari_truth.png", "adjusted Rand index against the truth") << "\n";

  md << "### The scenarios seen from above\n\n";
  for (const auto& picture : r.pictures) md << picture.caption << ":\n\n" << image(picture.file, picture.caption) << "\n";

  md << "## True objects by range and by kind\n\n"
     << "The object counts of the tables above and below, for MAD-C and the baseline, split by how far each true object is "
     << "from the nearest LiDAR of the scene (the horizontal distance from its centre, at the frame's instant, in metres) "
     << "and by its kind (the scene's label). Each cell: found whole / split / merged / missed of the true objects there, "
     << "summed over the frames (MAD-C over its complete frames, the baseline over those paired with one of its own).\n\n";
  {
    std::vector<BreakdownRow> sweep;
    for (const auto& a : r.alphas) {
      sweep.push_back({std::to_string(a.lidars) + " LiDARs, alpha " + fixedText(a.alpha, 1), &a.scores.madc_breakdown,
                       &a.scores.baseline_breakdown});
    }
    std::vector<BreakdownRow> sizes;
    for (const auto& z : r.sizes) {
      sizes.push_back({sceneLabel(z.objects, z.lidars), &z.scores.madc_breakdown, &z.scores.baseline_breakdown});
    }
    md << "The alpha sweep (scenes of " << plan.accuracy_objects << " objects):\n\n"
       << objectBreakdownMarkdown("configuration", sweep) << "\nThe scene sizes (alpha " << fixedText(kPaperAlpha, 1)
       << "):\n\n" << objectBreakdownMarkdown("scene", sizes) << "\n";
  }

  md << "## Ellipsoid comparisons with and without delimiting boxes (paper Table 1)\n\n"
     << "Exact intersection tests per frame when MERGE prunes with the delimiting boxes / pairs an all-pairs MERGE would test, "
     << "over the maps the edges shipped (mergeAll, the root's code). Paper, 10 / 50 / 100 objects at Lambda_2: 16/168, "
     << "72/3610, 105/12618; at Lambda_7: 164/2951, 804/56477, 2049/203423.\n\n| objects |";
  for (const int k : plan.lidar_counts) md << " " << k << " LiDARs |";
  md << "\n|---|";
  for (std::size_t i = 0; i < plan.lidar_counts.size(); ++i) md << "---|";
  md << "\n";
  for (const int objects : plan.object_counts) {
    md << "| " << objects << " |";
    for (const int k : plan.lidar_counts) {
      for (const auto& z : r.sizes) {
        if (z.objects == objects && z.lidars == k) {
          md << " " << fixedText(z.scores.pairs_tested_per_epoch, 0) << " / " << fixedText(z.scores.pairs_all_per_epoch, 0) << " |";
        }
      }
    }
    md << "\n";
  }

  md << "\n## Bytes and times (paper Fig. 9 and Table 2)\n\n"
     << "Bytes: what the edges upload per frame (the protobuf messages of the services' wire format). Times: means of the "
     << "services' histograms (fogmap_clustering_seconds at the edges, fogmap_merge_seconds at the root, which for the "
     << "baseline is its central clustering). End to end: the sensor time of a frame to the root publishing its global map "
     << "(median over complete frames), on loopback. The paper reports two orders of magnitude fewer bytes than shipping "
     << "the point clouds; fogmap's baseline ships the pre-processed points (cropped, ground removed), the raw column the "
     << "scans as the sensors give them, in the same wire format.\n\n"
     << "| objects | LiDARs | bytes MAD-C | bytes baseline | ratio | bytes raw scans | ratio raw | local clustering ms | MERGE ms | baseline central ms | e2e MAD-C ms | e2e baseline ms |\n"
     << "|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& z : r.sizes) {
    const SceneScores& s = z.scores;
    md << "| " << z.objects << " | " << z.lidars << " | " << fixedText(s.madc_bytes_per_frame, 0) << " | "
       << fixedText(s.baseline_bytes_per_frame, 0) << " | " << fixedText(s.baseline_bytes_per_frame / std::max(1.0, s.madc_bytes_per_frame), 0)
       << "x | " << fixedText(s.raw_bytes_per_frame, 0) << " | " << fixedText(s.raw_bytes_per_frame / std::max(1.0, s.madc_bytes_per_frame), 0)
       << "x | " << fixedText(s.clustering_ms, 2) << " | " << fixedText(s.merge_ms, 3) << " | " << fixedText(s.baseline_clustering_ms, 2)
       << " | " << fixedText(s.madc_e2e_p50_ms, 1) << " | " << fixedText(s.baseline_e2e_p50_ms, 1) << " |\n";
  }
  md << "\n" << image("fig9_bytes.png", "bytes per frame") << "\n" << image("fig9_times.png", "processing times") << "\n";

  md << "## Every edge behind a " << fixedText(plan.link_mbit.value_or(0.0), 0) << " Mbit/s link (paper Table 2)\n\n";
  if (r.links.ran) {
    const SceneScores& s = r.links.scores;
    md << "Each edge in its own network namespace, its veth pair limited by tbf to " << fixedText(r.links.mbit, 0)
       << " Mbit/s both ways; " << r.links.lidars << " LiDARs, " << r.links.objects << " objects, frames at "
       << fixedText(r.links.rate_hz, 0) << " Hz. The paper estimates 19 s for MAD-C and 50 s for the baseline at Lambda_7 with "
       << "100 objects (2.6x), from 2 GHz CPUs and 10 Mbit/s; its baseline ships the point clouds whole.\n\n"
       << "| | MAD-C | baseline, pre-processed points | baseline / MAD-C | baseline, whole scans (the paper's) | whole scans / MAD-C |\n"
       << "|---|---|---|---|---|---|\n"
       << "| end to end per frame (p50) | " << fixedText(s.madc_e2e_p50_ms, 1) << " ms | " << fixedText(s.baseline_e2e_p50_ms, 1)
       << " ms | " << fixedText(s.baseline_e2e_p50_ms / std::max(1e-9, s.madc_e2e_p50_ms), 1) << "x | "
       << fixedText(r.links.raw_baseline_e2e_p50_ms, 1) << " ms | "
       << fixedText(r.links.raw_baseline_e2e_p50_ms / std::max(1e-9, s.madc_e2e_p50_ms), 1) << "x |\n"
       << "| bytes per frame | " << fixedText(s.madc_bytes_per_frame, 0) << " | " << fixedText(s.baseline_bytes_per_frame, 0) << " | "
       << fixedText(s.baseline_bytes_per_frame / std::max(1.0, s.madc_bytes_per_frame), 0) << "x | "
       << fixedText(s.raw_bytes_per_frame, 0) << " | " << fixedText(s.raw_bytes_per_frame / std::max(1.0, s.madc_bytes_per_frame), 0)
       << "x |\n\n"
       << "The whole-scan baseline's root pre-processes every scan (crop, voxel grid, ground removal) before it clusters them: "
       << fixedText(r.links.raw_baseline_merge_ms, 1) << " ms per frame.\n";
  } else {
    md << "SKIPPED: " << r.links.skipped << "\n";
  }
  if (r.tracking) md << "\n" << trackingSection(*r.tracking);
  return md.str();
}

}  // namespace

Status writeEvaluation(const EvalPlan& plan, const EvalResult& result) {
  std::error_code ec;
  std::filesystem::create_directories(plan.out, ec);
  if (ec) return ioError("cannot create " + plan.out.string() + ": " + ec.message());
  const std::filesystem::path doc = plan.doc.empty() ? plan.out / "evaluation.md" : plan.doc;
  for (const auto& [name, text] : std::vector<std::pair<std::string, std::string>>{
           {"accuracy.csv", accuracyCsv(result)},
           {"precision_recall.csv", precisionCsv(result)},
           {"costs.csv", costsCsv(result)},
           {"links.csv", linksCsv(result)},
           {"eval.json", evalJson(plan, result)}}) {
    if (Status s = writeTextFile(plan.out / name, text); !s) return s;
  }
  if (result.tracking) {
    if (Status s = writeTextFile(plan.out / "tracking.csv", trackingCsv(*result.tracking)); !s) return s;
  }
  return writeTextFile(doc, report(plan, result, doc));
}

}  // namespace fogmap::harness
