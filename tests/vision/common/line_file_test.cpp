#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <random>

#include "vision/common/segment.hpp"

using namespace mfcd::vision;

namespace {
std::string errorOf(const std::string& text) {
  try {
    parseLineText(text, "t.lines");
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST(LineFile, RoundTrips) {
  LineSet set;
  set.q = 60;
  set.size = cv::Size(120, 90);
  set.origin = cv::Point2f(60, 45);
  set.lines.push_back({cv::Point2f(10, 10), cv::Point2f(70, 10), 0, 61});
  set.lines.push_back({cv::Point2f(20, 30), cv::Point2f(20, 80), 30, 51});
  const auto path = std::filesystem::temp_directory_path() / "mfcd_roundtrip.lines";
  writeLineFile(path, set);
  const LineSet back = readLineFile(path);
  EXPECT_EQ(back.q, 60);
  EXPECT_EQ(back.size, set.size);
  EXPECT_FLOAT_EQ(back.origin.x, 60);
  ASSERT_EQ(back.lines.size(), 2u);
  EXPECT_EQ(back.lines[0].channel, 0);
  EXPECT_EQ(back.lines[1].channel, 30);
  EXPECT_FLOAT_EQ(back.lines[1].b.y, 80);
  std::filesystem::remove(path);
}

// An oriented set (edge polarity): the flag survives, and each channel comes back from its
// endpoints' direction over the full turn (a reversed segment is the other polarity).
TEST(LineFile, OrientedSetRoundTripsWithItsPolarity) {
  LineSet set;
  set.q = 120;
  set.oriented = true;
  set.size = cv::Size(120, 90);
  set.lines.push_back({cv::Point2f(10, 10), cv::Point2f(70, 10), 0, 61});
  set.lines.push_back({cv::Point2f(20, 80), cv::Point2f(20, 30), 90, 51});  // pointing up: 270 degrees
  const auto path = std::filesystem::temp_directory_path() / "mfcd_oriented.lines";
  writeLineFile(path, set);
  const LineSet back = readLineFile(path);
  EXPECT_TRUE(back.oriented);
  EXPECT_EQ(back.q, 120);
  ASSERT_EQ(back.lines.size(), 2u);
  EXPECT_EQ(back.lines[0].channel, 0);
  EXPECT_EQ(back.lines[1].channel, 90);
  // Without the polarity: 60 channels over pi, the endpoints as they were.
  const LineSet undirected = withoutPolarity(back);
  EXPECT_FALSE(undirected.oriented);
  EXPECT_EQ(undirected.q, 60);
  EXPECT_EQ(undirected.lines[1].channel, 30);
  EXPECT_EQ(undirected.lines[1].a, back.lines[1].a);
  std::filesystem::remove(path);
  EXPECT_NE(errorOf("mfcd-lines 1\nq 61\noriented 1\nsize 100 100\n1 1 9 9\n").find("even q"), std::string::npos);
  EXPECT_NE(errorOf("mfcd-lines 1\nq 60\noriented 2\n").find("t.lines:3: oriented must be 0 or 1"), std::string::npos);
}

TEST(LineFile, MalformedInputNamesFileLineAndReason) {
  EXPECT_NE(errorOf("").find("empty line file"), std::string::npos);
  EXPECT_NE(errorOf("hello 1\n").find("t.lines:1: not an mfcd line file"), std::string::npos);
  EXPECT_NE(errorOf("mfcd-lines 2\n").find("unsupported line file version"), std::string::npos);
  const std::string head = "mfcd-lines 1\nq 60\nsize 100 100\n";
  EXPECT_NE(errorOf(head + "1 2 3\n").find("t.lines:4: segment 'x1 y1 x2 y2': expected 4 numbers, got 3"),
            std::string::npos);
  EXPECT_NE(errorOf(head + "1 2 x 4\n").find("t.lines:4: segment 'x1 y1 x2 y2': 'x' is not a number"),
            std::string::npos);
  EXPECT_NE(errorOf(head + "5 5 5.2 5.1\n").find("t.lines:4: zero-length segment"), std::string::npos);
  EXPECT_NE(errorOf("mfcd-lines 1\nq 0\n").find("t.lines:2: q must be an integer"), std::string::npos);
  EXPECT_NE(errorOf("mfcd-lines 1\nq -4\n").find("q must be"), std::string::npos);
  EXPECT_NE(errorOf("mfcd-lines 1\nsize 100 100\n1 1 9 9\n").find("missing 'q"), std::string::npos);
  EXPECT_NE(errorOf("mfcd-lines 1\nq 60\n1 1 9 9\n").find("missing 'size"), std::string::npos);
  EXPECT_NE(errorOf(head).find("no segments"), std::string::npos);
  EXPECT_NE(errorOf(head + "1 1 nan 4\n").find("not a number"), std::string::npos);
}

TEST(LineFile, MissingFileIsReported) {
  try {
    readLineFile("/nonexistent/dir/x.lines");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/dir/x.lines: cannot open"), std::string::npos);
  }
}

// sortLongestFirst against its definition, std::stable_sort by length, on sets with many equal
// lengths (axis-aligned segments of integer length); the buffered form with buffers kept from a
// previous, larger call gives the same order.
TEST(SortLongestFirst, IsTheStableSortByLength) {
  std::mt19937 rng(12);
  std::vector<std::pair<float, int>> order;
  std::vector<LineSegment> scratch;
  for (int trial = 0; trial < 50; ++trial) {
    std::vector<LineSegment> lines(static_cast<size_t>(1 + rng() % (trial < 25 ? 60 : 8)));
    for (size_t i = 0; i < lines.size(); ++i) {
      const float x = static_cast<float>(rng() % 100), y = static_cast<float>(rng() % 100),
                  len = static_cast<float>(1 + rng() % 6);
      lines[i].a = {x, y};
      lines[i].b = rng() % 2 ? cv::Point2f(x + len, y) : cv::Point2f(x, y + len);
      lines[i].support = static_cast<int>(i);  // identifies the original position
    }
    std::vector<LineSegment> expected = lines;
    std::stable_sort(expected.begin(), expected.end(),
                     [](const LineSegment& p, const LineSegment& r) { return p.length() > r.length(); });
    std::vector<LineSegment> plain = lines, buffered = lines;
    sortLongestFirst(plain);
    sortLongestFirst(buffered, order, scratch);
    ASSERT_EQ(plain.size(), expected.size());
    for (size_t i = 0; i < expected.size(); ++i) {
      EXPECT_EQ(plain[i].support, expected[i].support) << "trial " << trial << " position " << i;
      EXPECT_EQ(buffered[i].support, expected[i].support) << "trial " << trial << " position " << i;
    }
  }
}
