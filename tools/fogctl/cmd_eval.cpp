// fogctl eval: the MAD-C paper's evaluation with the running services (harness/eval_run.hpp).
#include <cstdio>
#include <string>

#include "harness/eval_run.hpp"
#include "harness/launcher.hpp"
#include "pictures/eval_figures.hpp"
#include "tools/fogctl/args.hpp"
#include "tools/fogctl/commands.hpp"

namespace fogmap::cli {
namespace {

using harness::EvalPlan;
using harness::installStopHandlers;
using harness::quickEvalPlan;
using harness::runEvaluation;
using harness::writeEvaluation;

int runEval(int argc, char** argv) {
  const auto args = Args::parse(argc, argv, 2, {"out", "doc", "seed", "frames"}, {"quick", "no-links"});
  if (!args) return fail(args.error(), "fogctl eval");
  const bool quick = args->has("quick");
  EvalPlan plan = quick ? quickEvalPlan() : EvalPlan{};
  if (!quick) {
    plan.out = "docs/evaluation";
    plan.doc = "docs/evaluation.md";
  }
  if (args->has("out")) {
    plan.out = args->get("out");
    if (quick) plan.work = plan.out / "work";
  }
  if (args->has("doc")) plan.doc = args->get("doc");
  const auto seed = args->getInt("seed", static_cast<long>(plan.seed));
  if (!seed || *seed < 0) return fail(invalidArgument("--seed must be a non-negative integer"), "fogctl eval");
  plan.seed = static_cast<std::uint64_t>(*seed);
  const auto frames = args->getInt("frames", static_cast<long>(plan.frames));
  if (!frames || *frames < 1 || *frames > 100) return fail(invalidArgument("--frames must be in [1, 100]"), "fogctl eval");
  plan.frames = static_cast<std::uint64_t>(*frames);
  if (args->has("no-links")) plan.link_mbit.reset();
  plan.command = "fogctl eval";
  for (int i = 2; i < argc; ++i) plan.command += std::string(" ") + argv[i];
  installStopHandlers();
  std::printf("fogmap eval%s: results in %s\n", quick ? " --quick" : "", plan.out.c_str());
  auto result = runEvaluation(plan, [](const std::string& line) {
    std::printf("%s\n", line.c_str());
    std::fflush(stdout);
  });
  if (!result) return fail(result.error(), "fogctl eval");
  if (Status written = writeEvaluation(plan, *result); !written) return fail(written.error(), "fogctl eval");
  if (Status drawn = pictures::drawEvaluationFigures(plan, *result); !drawn) return fail(drawn.error(), "fogctl eval");
  std::printf("done in %.0f s: %s, report %s\n", result->seconds, plan.out.c_str(),
              (plan.doc.empty() ? plan.out / "evaluation.md" : plan.doc).c_str());
  return 0;
}

}  // namespace

Command evalCommand() {
  return {"eval",
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
          runEval};
}

}  // namespace fogmap::cli
