#include "common/tracking/track.hpp"

namespace fogmap::tracking {

const char* trackStateName(TrackState state) {
  switch (state) {
    case TrackState::kTentative:
      return "tentative";
    case TrackState::kConfirmed:
      return "confirmed";
    case TrackState::kLost:
      return "lost";
  }
  return "?";
}

}  // namespace fogmap::tracking
