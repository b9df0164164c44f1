// The BOP results CSV that mfc-detect writes: its header and rows split and convert the way the
// BOP toolkit's inout.load_bop_results reads them (7 comma-separated fields; R 9 and t 3
// space-separated numbers), and result file names parse as its parse_result_filename parses them.
#include "vision/dataset/bop_results.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

using namespace mfcd::vision;

namespace {

std::vector<std::string> split_on(const std::string& s, char sep) {
  std::vector<std::string> out;
  size_t from = 0;
  for (size_t at; (at = s.find(sep, from)) != std::string::npos; from = at + 1)
    out.push_back(s.substr(from, at - from));
  out.push_back(s.substr(from));
  return out;
}

// Python's float(), int() and str.split() as the toolkit applies them: the whole field must convert.
double py_float(const std::string& s) {
  size_t used = 0;
  const double v = std::stod(s, &used);
  EXPECT_EQ(s.find_first_not_of(" \t\n", used), std::string::npos) << "'" << s << "' is not a float";
  return v;
}
int py_int(const std::string& s) {
  size_t used = 0;
  const int v = std::stoi(s, &used);
  EXPECT_EQ(used, s.size()) << "'" << s << "' is not an int";
  return v;
}
std::vector<double> py_split_floats(const std::string& s) {
  std::istringstream in(s);
  std::vector<double> out;
  for (std::string w; in >> w;) out.push_back(py_float(w));
  return out;
}

cv::Matx33d rotation(const cv::Vec3d& w) {  // Rodrigues' formula
  const double th = cv::norm(w);
  const cv::Vec3d k = w / th;
  const cv::Matx33d Kx(0, -k[2], k[1], k[2], 0, -k[0], -k[1], k[0], 0);
  return cv::Matx33d::eye() + std::sin(th) * Kx + (1 - std::cos(th)) * Kx * Kx;
}

}  // namespace

TEST(BopResults, HeaderAndRowParseAsTheToolkitReadsThem) {
  EXPECT_STREQ(kBopResultsHeader, "scene_id,im_id,obj_id,score,R,t,time");
  BopResult r;
  r.scene_id = 12, r.im_id = 345, r.obj_id = 6, r.score = 0.8125;
  r.R = rotation({0.3, -1.2, 0.7});
  r.t_mm = {-12.25, 3.5, 287.0625};
  r.time_s = 0.4375;
  const std::string row = bop_results_row(r);
  ASSERT_FALSE(row.empty());
  EXPECT_EQ(row.back(), '\n');
  EXPECT_EQ(row.find('\n'), row.size() - 1) << "one line per estimate";
  const std::vector<std::string> f = split_on(row, ',');
  ASSERT_EQ(f.size(), 7u) << row;
  EXPECT_EQ(py_int(f[0]), 12);
  EXPECT_EQ(py_int(f[1]), 345);
  EXPECT_EQ(py_int(f[2]), 6);
  EXPECT_DOUBLE_EQ(py_float(f[3]), 0.8125);
  const std::vector<double> R = py_split_floats(f[4]);
  ASSERT_EQ(R.size(), 9u) << f[4];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) EXPECT_NEAR(R[static_cast<size_t>(3 * i + j)], r.R(i, j), 1e-9) << i << j;  // row-major
  const std::vector<double> t = py_split_floats(f[5]);
  ASSERT_EQ(t.size(), 3u) << f[5];
  for (int k = 0; k < 3; ++k) EXPECT_DOUBLE_EQ(t[static_cast<size_t>(k)], r.t_mm[k]);  // mm, as written
  EXPECT_DOUBLE_EQ(py_float(f[6]), 0.4375);                                            // seconds
}

TEST(BopResults, NonFiniteNumbersAreRefused) {
  BopResult r;
  r.scene_id = 2, r.im_id = 9, r.obj_id = 4;
  r.t_mm[2] = std::numeric_limits<double>::quiet_NaN();
  try {
    bop_results_row(r);
    ADD_FAILURE() << "a NaN translation was written";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("scene 2 image 9 object 4"), std::string::npos) << e.what();
  }
  r.t_mm[2] = 300;
  r.R(1, 1) = std::numeric_limits<double>::infinity();
  EXPECT_THROW(bop_results_row(r), std::invalid_argument);
  r.R(1, 1) = 1;
  r.score = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(bop_results_row(r), std::invalid_argument);
  r.score = 1;
  EXPECT_NO_THROW(bop_results_row(r));  // time -1: not measured, as BOP allows
}

TEST(BopResults, FileNamesParseAsTheToolkitParsesThem) {
  const auto a = parse_bop_results_name("/tmp/results/mfcdetect_mfcsim-test.csv");
  ASSERT_TRUE(a);
  EXPECT_EQ(a->method, "mfcdetect");
  EXPECT_EQ(a->dataset, "mfcsim");
  EXPECT_EQ(a->split, "test");
  EXPECT_EQ(a->split_type, "");
  const auto b = parse_bop_results_name("mfc-detect_tless-test-primesense_run2.csv");
  ASSERT_TRUE(b);
  EXPECT_EQ(b->method, "mfc-detect");
  EXPECT_EQ(b->dataset, "tless");
  EXPECT_EQ(b->split, "test");
  EXPECT_EQ(b->split_type, "primesense");
  for (const char* bad : {"results.csv", "mfcdetect_mfcsim.csv", "_mfcsim-test.csv", "m_-test.csv", "m_mfcsim-.csv",
                          "m_mfcsim-test-.csv", "m_mfcsim_x-test.csv"})
    EXPECT_FALSE(parse_bop_results_name(bad)) << bad;
}
