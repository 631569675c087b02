#pragma once
// Object-level accuracy broken down by where a true object is and by what it is: the per-object
// outcomes of matchEachObject (common/scoring) grouped over a simulated scene's truth, by range band
// (horizontal distance to the nearest LiDAR) and by kind (the scene's labels). Pure: scene and
// outcomes in, counts and report text out.
#include <array>
#include <map>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/base/status.hpp"
#include "common/scoring/object_match.hpp"
#include "common/sim/scene.hpp"
#include "harness/report_text.hpp"

namespace fogmap::harness {

// The range bands, nearest first: the horizontal distance in metres from a true object's centre
// (sim::poseAt at the frame's instant, the centre the tracking scores use) to the NEAREST LiDAR of
// the scene, in [0, 10), [10, 20), [20, 40) and [40, infinity).
inline constexpr std::array<const char*, 4> kRangeBands = {"0-10", "10-20", "20-40", "40+"};
// The kind of an object without a label.
inline constexpr const char* kOtherKind = "other";

// The band of a distance; "40+" also for one that is not finite (a scene without LiDARs).
std::string rangeBand(double distance_m);
// The horizontal distance from `xy` to the nearest LiDAR of `scene`; infinity when it has none.
double nearestLidarDistance(const sim::Scene& scene, const Eigen::Vector2d& xy);
// What an object is, as the scene names it: its label ("person", "car", "crate", ...), or kOtherKind.
std::string objectKind(const sim::SceneObject& object);

// Counts of true objects (ObjectMatch's definitions) per range band and per kind.
struct ObjectBreakdown {
  std::map<std::string, ObjectMatch> by_range_band;  // keys: kRangeBands
  std::map<std::string, ObjectMatch> by_kind;        // keys: objectKind of the scene's objects
};

// Every band and every kind of `scene` with all counts zero: what sums over frames start from, so
// that a report lists the bands and kinds no counted object fell in too.
ObjectBreakdown emptyBreakdown(const sim::Scene& scene);

// One frame's outcomes grouped: each object by where it is at scene time `time_s` and by its kind.
// Starts from emptyBreakdown(scene). Errors when an outcome's object is not one of the scene's.
Expected<ObjectBreakdown> breakDownObjects(const sim::Scene& scene, double time_s, std::span<const ObjectOutcome> outcomes);

// `m` added to `sum`, count by count; `frame` added to `sum`, band by band and kind by kind.
void addObjectMatch(ObjectMatch& sum, const ObjectMatch& m);
void addBreakdown(ObjectBreakdown& sum, const ObjectBreakdown& frame);

// Where the missed objects of `outcomes` are at scene time `time_s` (their centres on the ground,
// sim::poseAt), in the outcomes' order. Errors when an outcome's object is not one of the scene's.
Expected<std::vector<Eigen::Vector2d>> missedCentres(const sim::Scene& scene, double time_s,
                                                     std::span<const ObjectOutcome> outcomes);

// {"true", "found_whole", "split", "merged", "missed"} of `m`.
Json objectMatchReport(const ObjectMatch& m);
// {"madc": {"0-10": objectMatchReport, ... every band in order}, "baseline": {...}}.
Json rangeBandReport(const ObjectBreakdown& madc, const ObjectBreakdown& baseline);
// {"madc": {kind: objectMatchReport, ...}, "baseline": {...}}.
Json kindReport(const ObjectBreakdown& madc, const ObjectBreakdown& baseline);

// What fogctl demo prints: a table per system (MAD-C, then the baseline), a row per band and per
// kind, columns true / found whole / split / merged / missed; each line indented by two spaces.
std::string objectBreakdownText(const ObjectBreakdown& madc, const ObjectBreakdown& baseline);

// One configuration of an evaluation (e.g. "3 LiDARs, alpha 1.5") with its two systems' counts.
struct BreakdownRow {
  std::string configuration;
  const ObjectBreakdown* madc = nullptr;
  const ObjectBreakdown* baseline = nullptr;
};
// Two Markdown tables, by range band and by kind (the kinds of every row), a row per configuration
// and system; each cell "found whole / split / merged / missed of true".
std::string objectBreakdownMarkdown(const std::string& configuration_header, std::span<const BreakdownRow> rows);

}  // namespace fogmap::harness
