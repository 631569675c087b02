#pragma once
// A global object's box and class from its views (docs/design.md "Oriented boxes"). Each ellipsoid
// an edge ships may carry its cluster's oriented box and LiDAR class; an object merged from several
// sensors has one view per ellipsoid. Both rules below are functions of the object's set of views
// (its ellipsoids in canonical order), so like MERGE they do not depend on the order in which maps
// arrive or are merged.
#include <optional>

#include "common/geometry/map.hpp"
#include "common/geometry/object_class.hpp"
#include "common/geometry/oriented_box.hpp"

namespace fogmap {

// The object's box: the view with a box and the most points gives the axis (ties: the smallest id);
// the box is the smallest one on that axis that holds every view's footprint, from the lowest bottom
// to the highest top (length >= width: the axis turns by 90 degrees where the extent across it is
// the larger). Anchor: the best view's own when it is the only view with a box, else kNone (several
// sensors see several faces). Nothing when no view has a box.
std::optional<OrientedBox> objectBox(const MapObject& object);

// The object's class: each labelled view votes for its class with weight confidence x points; the
// class of largest weight wins (ties: the smaller class number), with confidence its weight over the
// points of all labelled views: views that disagree lower it. Nothing when no view has a label.
std::optional<ObjectLabel> objectLabel(const MapObject& object);

}  // namespace fogmap
