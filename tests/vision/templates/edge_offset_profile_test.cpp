// EdgeOffsetProfile: interpolation between its bins, and the measurement on the simulated camera,
// which must show the non-maximum suppression bias the pose fit corrects: edges near an image axis
// detected inside the outline, diagonal ones on it, the same every quarter turn.
#include "vision/templates/edge_offset_profile.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <numbers>

using namespace mfcd::vision;
namespace fs = std::filesystem;

namespace {

CameraConfig sim_camera() { return load_camera_config(fs::path(MFC_SOURCE_DIR) / "config/camera-sim.yaml"); }

double deg(double d) { return d * std::numbers::pi / 180; }

}  // namespace

TEST(EdgeOffsetProfile, InterpolatesBetweenBinsAroundTheTurn) {
  EdgeOffsetProfile p;
  EXPECT_EQ(p.at(1.0), 0.0);  // empty: no correction
  p.offset_px.resize(EdgeOffsetProfile::kBins);
  for (int k = 0; k < EdgeOffsetProfile::kBins; ++k) p.offset_px[k] = 0.01f * k;
  EXPECT_NEAR(p.at(0), 0.0, 1e-6);
  EXPECT_NEAR(p.at(deg(10)), 0.02, 1e-6);                 // bin 2 is centred at 10 degrees
  EXPECT_NEAR(p.at(deg(12.5)), 0.025, 1e-6);              // halfway to bin 3
  EXPECT_NEAR(p.at(deg(357.5)), (0.71 + 0.0) / 2, 1e-6);  // between the last bin and the first
  EXPECT_NEAR(p.at(deg(-5)), 0.71, 1e-6);
  EXPECT_NEAR(p.at(deg(365)), 0.01, 1e-6);
  EXPECT_NEAR(p.at(deg(725)), 0.01, 1e-6);
}

TEST(EdgeOffsetProfile, MeanNearTakesTheSameBandInAllFourQuarters) {
  EdgeOffsetProfile p;
  EXPECT_EQ(p.mean_near(0, 10), 0.0);
  p.offset_px.assign(EdgeOffsetProfile::kBins, 0.0f);
  // Bins 0-2 and 70-71 (within 10 degrees of 0) and their copies a quarter, half and three
  // quarters round: 20 bins; bin 3 (15 degrees) is outside.
  for (int q = 0; q < 4; ++q)
    for (int k : {-2, -1, 0, 1, 2, 3}) p.offset_px[(18 * q + k + 72) % 72] = k == 3 ? 9.0f : 1.0f + q;
  EXPECT_NEAR(p.mean_near(0, 10), 2.5, 1e-6);
  EXPECT_NEAR(p.mean_near(15, 0), 9.0, 1e-6);  // exactly the four bins at 15 + k x 90 degrees
  EXPECT_NEAR(p.mean_near(45, 10), 0.0, 1e-6);
  EXPECT_NEAR(p.mean_near(90, 10), 2.5, 1e-6);  // 90 is 0 a quarter round
}

TEST(EdgeOffsetProfile, AxisAlignedEdgesLieInsideTheOutlineDiagonalOnesOnIt) {
  const CameraConfig cam = sim_camera();
  EdgeProfileConditions views;  // as the template views are rendered
  views.noise = false;
  views.floor_gap_mm = 15;
  const EdgeOffsetProfile off = measure_edge_offset_profile(cam, 300, views);
  const EdgeOffsetProfile on = measure_edge_offset_profile(cam, 300, EdgeProfileConditions{});
  ASSERT_EQ(off.offset_px.size(), static_cast<size_t>(EdgeOffsetProfile::kBins));
  for (const auto* p : {&off, &on}) {
    const double axis = p->mean_near(0, 10), diagonal = p->mean_near(45, 10);
    EXPECT_LT(axis, -0.05);
    EXPECT_LT(axis, diagonal - 0.05);
    EXPECT_NEAR(diagonal, 0, 0.05);
    // The pixel grid and the ring of flashes look the same every quarter turn. (Not checked in the
    // steep steps between the two plateaus, 15-30 degrees off an axis, where a bin's few turns
    // fall at different sub-pixel phases.)
    for (int k = 0; k < EdgeOffsetProfile::kBins; ++k) {
      const int in_quarter = (5 * k) % 90;
      if ((in_quarter > 10 && in_quarter < 35) || (in_quarter > 55 && in_quarter < 80)) continue;
      for (int quarter = 1; quarter < 4; ++quarter)
        EXPECT_NEAR(p->offset_px[k], p->offset_px[(k + 18 * quarter) % EdgeOffsetProfile::kBins], 0.15)
            << "bin " << k << ", quarter " << quarter;
    }
  }
  // Without noise a tie across an axis-aligned edge always goes to the occluding pixel.
  EXPECT_LT(off.mean_near(0, 10), on.mean_near(0, 10) - 0.1);
}

TEST(EdgeOffsetProfile, RefusesBadArguments) {
  EXPECT_THROW(measure_edge_offset_profile(sim_camera(), 10, {}), std::invalid_argument);
  EdgeProfileConditions c;
  c.turns = 2;
  EXPECT_THROW(measure_edge_offset_profile(sim_camera(), 300, c), std::invalid_argument);
}
