#pragma once
// Numbers as fogctl's reports write them: fixed decimals in tables and printed figures, JSON
// numbers in eval.json and the demo's report. Pure.
#include <string>

namespace fogmap::cli {

// `v` with `digits` decimals; "n/a" when it is not finite (a ratio without a denominator).
std::string fixedText(double v, int digits);

// `v` as a JSON number with 10 significant digits; null when it is not finite (JSON has no NaN).
std::string jsonNumber(double v);

}  // namespace fogmap::cli
