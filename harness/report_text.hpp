#pragma once
// Numbers as fogctl's reports write them: fixed decimals in tables and printed figures, JSON
// numbers in the JSON reports (eval.json, the demo's and the fault harness's reports). Pure.
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "common/base/status.hpp"

namespace fogmap::harness {

// The JSON reports keep their keys in the order written.
using Json = nlohmann::ordered_json;

// `v` with `digits` decimals; "n/a" when it is not finite (a ratio without a denominator).
std::string fixedText(double v, int digits);

// printf's formatting into a string (lines of a table); the compiler checks the arguments.
[[gnu::format(printf, 1, 2)]] std::string formatText(const char* format, ...);

// `v` as a JSON number rounded to 10 significant digits; null when it is not finite (JSON has no NaN).
Json jsonNumber(double v);

// A JSON report as written to a file or stdout: indented by two spaces, one newline at the end;
// bytes that are not UTF-8 (a path, say) replaced rather than refused.
std::string jsonText(const Json& report);

// Writes `text` to `file` (replacing it); an I/O error naming the file when it cannot.
Status writeTextFile(const std::filesystem::path& file, const std::string& text);

}  // namespace fogmap::harness
