#include "pictures/eval_figures.hpp"

#include <algorithm>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include "harness/report_text.hpp"
#include "pictures/plot.hpp"
#include "pictures/scene_picture.hpp"

namespace fogmap::pictures {
namespace {

using harness::AlphaRow;
using harness::EvalPlan;
using harness::EvalResult;
using harness::fixedText;
using harness::kPaperAlpha;
using harness::PrecisionRow;

// Every distinct value of a field over rows, sorted.
template <class Row, class F>
std::vector<double> distinct(const std::vector<Row>& rows, F field) {
  std::set<double> values;
  for (const auto& r : rows) values.insert(static_cast<double>(field(r)));
  return {values.begin(), values.end()};
}

Status drawPlots(const EvalPlan& plan, const EvalResult& r) {
  const auto& out = plan.out;
  std::vector<double> lidar_ticks(plan.lidar_counts.begin(), plan.lidar_counts.end());
  {  // Fig. 6: precision and recall against alpha, averaged over the LiDAR counts.
    PlotSpec spec;
    spec.title = "Ellipsoid precision and recall against the truth (" + std::to_string(plan.accuracy_objects) +
                 " objects, " + std::to_string(plan.lidar_counts.size()) + " LiDAR counts)";
    spec.x_label = "alpha (confidence step)";
    spec.y_label = "mean over local clusters";
    spec.y_min = 0.0;
    spec.y_max = 1.0;
    for (const bool aura : {true, false}) {
      PlotSeries precision{std::string("precision") + (aura ? ", with aura" : ", no aura"), {}, {}, {}, {}, !aura};
      PlotSeries recall{std::string("recall") + (aura ? ", with aura" : ", no aura"), {}, {}, {}, {}, !aura};
      for (const double alpha : distinct(r.precision, [](const PrecisionRow& p) { return p.alpha; })) {
        double p_sum = 0.0, r_sum = 0.0;
        std::size_t n = 0;
        for (const auto& row : r.precision) {
          if (row.alpha != alpha || row.aura != aura) continue;
          p_sum += row.precision * static_cast<double>(row.clusters);
          r_sum += row.recall * static_cast<double>(row.clusters);
          n += row.clusters;
        }
        if (n == 0) continue;
        precision.x.push_back(alpha);
        precision.y.push_back(p_sum / static_cast<double>(n));
        recall.x.push_back(alpha);
        recall.y.push_back(r_sum / static_cast<double>(n));
      }
      spec.series.push_back(precision);
      spec.series.push_back(recall);
    }
    if (Status s = drawLinePlot(out / "fig6_precision_recall.png", spec); !s) return s;
  }
  {  // Fig. 7: Rand index against the baseline over alpha, one line per LiDAR count.
    PlotSpec spec;
    spec.title = "MAD-C against the baseline: Rand index over local clusters";
    spec.x_label = "alpha (confidence step)";
    spec.y_label = "Rand index";
    spec.x_ticks = plan.alphas;
    for (const int lidars : plan.lidar_counts) {
      PlotSeries series{std::to_string(lidars) + " LiDARs", {}, {}, {}, {}, false};
      for (const auto& a : r.alphas) {
        if (a.lidars != lidars) continue;
        series.x.push_back(a.alpha);
        series.y.push_back(a.scores.madc_vs_baseline.rand_index);
      }
      if (!series.x.empty()) spec.series.push_back(series);
    }
    if (!spec.series.empty()) {
      if (Status s = drawLinePlot(out / "fig7_rand_index.png", spec); !s) return s;
    }
  }
  {  // Fig. 8: against the truth over the LiDAR counts, one line per alpha and the baseline.
    PlotSpec spec;
    spec.title = "Against the truth: adjusted Rand index over points, " + std::to_string(plan.accuracy_objects) + " objects";
    spec.x_label = "LiDARs";
    spec.y_label = "adjusted Rand index";
    spec.x_ticks = lidar_ticks;
    for (const double alpha : plan.alphas) {
      PlotSeries series{"MAD-C-ext, alpha " + fixedText(alpha, 1), {}, {}, {}, {}, false};
      for (const auto& a : r.alphas) {
        if (a.alpha != alpha) continue;
        series.x.push_back(a.lidars);
        series.y.push_back(a.scores.madc_vs_truth.adjusted_rand_index);
      }
      if (!series.x.empty()) spec.series.push_back(series);
    }
    PlotSeries base{"baseline (central clustering)", {}, {}, {}, {}, true};
    for (const auto& a : r.alphas) {
      if (a.alpha != kPaperAlpha) continue;
      base.x.push_back(a.lidars);
      base.y.push_back(a.scores.baseline_vs_truth.adjusted_rand_index);
    }
    if (!base.x.empty()) spec.series.push_back(base);
    if (!spec.series.empty()) {
      if (Status s = drawLinePlot(out / "fig8_ari_truth.png", spec); !s) return s;
    }
  }
  {  // Fig. 9: bytes per frame against LiDARs, per scene size (log).
    PlotSpec spec;
    spec.title = "Bytes the edges ship per frame: MAD-C, the baseline, the raw scans";
    spec.x_label = "LiDARs";
    spec.y_label = "bytes per frame (all edges)";
    spec.log_y = true;
    spec.x_ticks = lidar_ticks;
    for (const int objects : plan.object_counts) {
      PlotSeries madc{"MAD-C, " + std::to_string(objects) + " objects", {}, {}, {}, {}, false};
      PlotSeries base{"baseline, " + std::to_string(objects) + " objects", {}, {}, {}, {}, true};
      PlotSeries raw{"raw scans, " + std::to_string(objects) + " objects", {}, {}, {}, {}, true};
      for (const auto& z : r.sizes) {
        if (z.objects != objects) continue;
        madc.x.push_back(z.lidars);
        madc.y.push_back(std::max(1.0, z.scores.madc_bytes_per_frame));
        base.x.push_back(z.lidars);
        base.y.push_back(std::max(1.0, z.scores.baseline_bytes_per_frame));
        raw.x.push_back(z.lidars);
        raw.y.push_back(std::max(1.0, z.scores.raw_bytes_per_frame));
      }
      spec.series.push_back(madc);
      spec.series.push_back(base);
      if (objects == plan.object_counts.back()) spec.series.push_back(raw);  // the scans hardly depend on the objects
    }
    if (Status s = drawLinePlot(out / "fig9_bytes.png", spec); !s) return s;
  }
  {  // Fig. 9 (middle): stage times at the largest scene.
    const int objects = plan.object_counts.back();
    PlotSpec spec;
    spec.title = "Processing time per frame, " + std::to_string(objects) + " objects";
    spec.x_label = "LiDARs";
    spec.y_label = "milliseconds (mean)";
    spec.log_y = true;
    spec.x_ticks = lidar_ticks;
    PlotSeries local{"MAD-C local clustering, per edge", {}, {}, {}, {}, false};
    PlotSeries merge{"MAD-C MERGE at the root", {}, {}, {}, {}, false};
    PlotSeries central{"baseline central clustering", {}, {}, {}, {}, true};
    for (const auto& z : r.sizes) {
      if (z.objects != objects) continue;
      local.x.push_back(z.lidars);
      local.y.push_back(std::max(1e-3, z.scores.clustering_ms));
      merge.x.push_back(z.lidars);
      merge.y.push_back(std::max(1e-3, z.scores.merge_ms));
      central.x.push_back(z.lidars);
      central.y.push_back(std::max(1e-3, z.scores.baseline_clustering_ms));
    }
    spec.series = {local, merge, central};
    if (Status s = drawLinePlot(out / "fig9_times.png", spec); !s) return s;
  }
  return {};
}

}  // namespace

Status drawEvaluationFigures(const EvalPlan& plan, const EvalResult& result) {
  std::error_code ec;
  std::filesystem::create_directories(plan.out, ec);
  if (ec) return ioError("cannot create " + plan.out.string() + ": " + ec.message());
  for (const harness::EvalPicture& p : result.pictures) {
    if (Status drawn = drawSceneBirdseye(plan.out / p.file, p.global, p.view, p.scene, p.topology, p.title); !drawn) return drawn;
  }
  return drawPlots(plan, result);
}

}  // namespace fogmap::pictures
