#pragma once
// The evaluation's figures (fogctl eval): a bird's-eye picture per scenario of the alpha sweep and
// the line charts of the MAD-C paper's Figs. 6 to 9, drawn from the harness's EvalResult under the
// file names the report (harness/eval_run) links to.
#include "common/base/status.hpp"
#include "harness/eval_run.hpp"

namespace fogmap::pictures {

// Draws into plan.out: every result.pictures entry, fig6_precision_recall.png, fig7_rand_index.png
// and fig8_ari_truth.png (when the sweep has their points), fig9_bytes.png and fig9_times.png.
// Errors: a picture that cannot be drawn or written (naming the file).
Status drawEvaluationFigures(const harness::EvalPlan& plan, const harness::EvalResult& result);

}  // namespace fogmap::pictures
