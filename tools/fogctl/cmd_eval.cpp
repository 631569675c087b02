// fogctl eval: the MAD-C paper's evaluation with the running services (tools/fogctl/eval_run.hpp).
#include <cstdio>
#include <string>

#include "tools/fogctl/args.hpp"
#include "tools/fogctl/commands.hpp"
#include "tools/fogctl/eval_run.hpp"
#include "tools/fogctl/launcher.hpp"

namespace fogmap::cli {

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
  std::printf("done in %.0f s: %s, report %s\n", result->seconds, plan.out.c_str(),
              (plan.doc.empty() ? plan.out / "evaluation.md" : plan.doc).c_str());
  return 0;
}

}  // namespace fogmap::cli
