// The pictures of a harness run (pictures/scene_picture): which tracks a picture shows, and the
// trails they carry.
#include "pictures/scene_picture.hpp"

#include <gtest/gtest.h>

#include <vector>

namespace fogmap::pictures {
namespace {

using harness::PublishedTracks;

TEST(TrackScoring, APicturesTracksCarryTheirRecentPositionsAsTrails) {
  std::vector<PublishedTracks> lists(6);
  for (int k = 0; k < 6; ++k) {
    tracking::Track walking;
    walking.id = 1;
    walking.label = "person";
    walking.state = k < 2 ? tracking::TrackState::kTentative : tracking::TrackState::kConfirmed;
    walking.position = {1.0 * k, 0.0};
    lists[static_cast<std::size_t>(k)].tracks.push_back(walking);
  }
  tracking::Track fresh;  // tentative in the last list: not drawn
  fresh.id = 2;
  lists.back().tracks.push_back(fresh);
  tracking::Track lost;
  lost.id = 3;
  lost.state = tracking::TrackState::kLost;
  lists.back().tracks.push_back(lost);
  const auto drawn = birdseyeTracks(lists, 5, 3);
  ASSERT_EQ(drawn.size(), 2U);
  EXPECT_EQ(drawn[0].id, 1U);
  EXPECT_EQ(drawn[0].label, "person");
  EXPECT_TRUE(drawn[0].confirmed);
  EXPECT_TRUE(drawn[0].position.isApprox(Eigen::Vector2d(5, 0)));
  ASSERT_EQ(drawn[0].trail.size(), 3U) << "the three lists before, oldest first";
  EXPECT_TRUE(drawn[0].trail[0].isApprox(Eigen::Vector2d(2, 0)));
  EXPECT_TRUE(drawn[0].trail[2].isApprox(Eigen::Vector2d(4, 0)));
  EXPECT_EQ(drawn[1].id, 3U);
  EXPECT_FALSE(drawn[1].confirmed);
  EXPECT_TRUE(drawn[1].trail.empty());
  EXPECT_EQ(birdseyeTracks(lists, 1, 10).size(), 0U) << "only a tentative track then";
  EXPECT_EQ(birdseyeTracks(lists, 6, 3).size(), 0U) << "out of range";
}

}  // namespace
}  // namespace fogmap::pictures
