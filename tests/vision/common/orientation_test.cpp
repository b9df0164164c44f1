#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "vision/common/digital_line.hpp"
#include "vision/common/orientation.hpp"

using namespace mfcd::vision;

TEST(OrientationChannels, RejectsNonPositiveOrHugeQ) {
  EXPECT_THROW(OrientationChannels(0), std::invalid_argument);
  EXPECT_THROW(OrientationChannels(-3), std::invalid_argument);
  EXPECT_THROW(OrientationChannels(181), std::invalid_argument);
  try {
    OrientationChannels bad(0);
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("q must be"), std::string::npos);
  }
}

TEST(OrientationChannels, QuantisesUndirectedAngles) {
  const OrientationChannels ch(60);
  for (int c = 0; c < 60; ++c) {
    EXPECT_EQ(ch.channelOf(ch.angleOf(c)), c);
    EXPECT_EQ(ch.channelOf(ch.angleOf(c) + std::numbers::pi), c) << "directions are modulo pi";
    EXPECT_EQ(ch.channelOf(ch.angleOf(c) - std::numbers::pi), c);
    EXPECT_EQ(ch.channelOf(ch.angleOf(c) + 0.49 * ch.step()), c);
  }
  EXPECT_EQ(ch.channelOf(std::numbers::pi - 0.1 * ch.step()), 0) << "wraps to channel 0 near pi";
}

TEST(OrientationChannels, CircularDistance) {
  const OrientationChannels ch(60);
  EXPECT_EQ(ch.distance(0, 59), 1);
  EXPECT_EQ(ch.distance(59, 0), 1);
  EXPECT_EQ(ch.distance(0, 30), 30);
  EXPECT_EQ(ch.distance(10, 45), 25);
  for (int a = 0; a < 60; ++a)
    for (int b = 0; b < 60; ++b) {
      EXPECT_EQ(ch.distance(a, b), ch.distance(b, a));
      EXPECT_LE(ch.distance(a, b), 30);
    }
}

TEST(DigitalLineTable, PatternFollowsTheChannelSlope) {
  const OrientationChannels ch(60);
  const DigitalLineTable t(ch, 700, 500);
  for (int c = 0; c < 60; ++c) {
    const int16_t* m = t.minor(c);
    const double phi = ch.angleOf(c);
    const double slope = t.xMajor(c) ? std::tan(phi) : 1.0 / std::tan(phi);
    ASSERT_LE(std::abs(slope), 1.0 + 1e-9);
    const int extent = t.xMajor(c) ? 700 : 500;
    for (int k = 1; k <= extent; ++k) {
      EXPECT_LE(std::abs(m[k] - m[k - 1]), 1) << "pattern steps by at most one pixel";
      EXPECT_LE(std::abs(m[k] - k * slope), 0.5 + 1e-9);
    }
  }
}

// Oriented channels (edge polarity): q channels over a full turn; c and c + q/2 are one
// undirected direction with its two polarities, sharing one digital pattern.
TEST(OrientationChannels, OrientedChannelsSpanAFullTurn) {
  const OrientationChannels ch(120, true);
  const OrientationChannels undirected(60);
  EXPECT_TRUE(ch.oriented());
  EXPECT_DOUBLE_EQ(ch.period(), 2 * std::numbers::pi);
  EXPECT_EQ(ch.step(), undirected.step()) << "the same angular resolution, bit for bit";
  for (int c = 0; c < 120; ++c) {
    EXPECT_EQ(ch.channelOf(ch.angleOf(c)), c);
    EXPECT_EQ(ch.channelOf(ch.angleOf(c) + 2 * std::numbers::pi), c) << "directions are modulo 2 pi";
    EXPECT_EQ(ch.channelOf(ch.angleOf(c) + std::numbers::pi), (c + 60) % 120) << "reversed is the other polarity";
    EXPECT_EQ(ch.channelOf(ch.angleOf(c)) % 60, undirected.channelOf(ch.angleOf(c)));
    EXPECT_EQ(ch.xMajor(c), undirected.xMajor(c % 60));
    EXPECT_EQ(ch.minorSlope(c), undirected.minorSlope(c % 60)) << "one pattern for both polarities";
  }
  EXPECT_EQ(ch.distance(0, 60), 60) << "opposite polarities are half a turn apart";
  EXPECT_EQ(ch.distance(1, 119), 2);
  EXPECT_EQ(ch.channelOf(2 * std::numbers::pi - 0.1 * ch.step()), 0) << "wraps to channel 0 near 2 pi";
  EXPECT_THROW(OrientationChannels(59, true), std::invalid_argument);
}

// The x-major choice is the direction's, whatever the period: |cos| >= |sin| at the centre
// (45-degree channels x-major).
TEST(OrientationChannels, XMajorFollowsTheDirection) {
  for (const bool oriented : {false, true})
    for (const int q : {8, 12, 60, 120, 180}) {
      const OrientationChannels ch(q, oriented);
      for (int c = 0; c < q; ++c) {
        const double phi = ch.angleOf(c);
        const double ac = std::abs(std::cos(phi)), as = std::abs(std::sin(phi));
        if (std::abs(ac - as) < 1e-9)
          EXPECT_TRUE(ch.xMajor(c)) << "q " << q << " c " << c;
        else
          EXPECT_EQ(ch.xMajor(c), ac > as) << "q " << q << " oriented " << oriented << " c " << c;
      }
    }
}
