// The pipeline's parameter table (vision/pipeline/pipeline_parameters.hpp): every key once, every
// default in its range, setting and refusing by key, and docs/configuration.md's vision table
// equal to the one the table makes.
#include "vision/pipeline/pipeline_parameters.hpp"

#include "vision/pipeline/bin_picking_pipeline.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <set>
#include <sstream>
#include <string>

namespace mfcd::vision {
namespace {

using Type = PipelineParameter::Type;

TEST(PipelineParameters, EveryKeyOnceWithItsDefaultInRange) {
  std::set<std::string> keys;
  for (const PipelineParameter& p : pipeline_parameters()) {
    EXPECT_TRUE(keys.insert(p.key).second) << p.key << " is in the table twice";
    EXPECT_TRUE(p.in_range(p.default_value()))
        << p.key << " default " << p.default_value() << " is not " << p.range_text();
    EXPECT_LE(p.min, p.max) << p.key;
    EXPECT_GT(std::string(p.meaning).size(), 10u) << p.key;
    if (p.type == Type::boolean) {
      EXPECT_TRUE(p.min == 0 && p.max == 1) << p.key;
    }
    EXPECT_EQ(find_pipeline_parameter(p.key), &p);
  }
  EXPECT_EQ(find_pipeline_parameter("no_such_key"), nullptr);
  EXPECT_NO_THROW(validate_parameters(PipelineConfig{}));
}

// Each parameter's accessors reach its own field and no other: setting one to another value in
// range changes exactly that parameter.
TEST(PipelineParameters, EachKeySetsItsOwnField) {
  for (const PipelineParameter& p : pipeline_parameters()) {
    PipelineConfig c;
    double v = std::isinf(p.max) ? p.min + 1 : p.max;
    if (v == p.default_value()) v = p.min;
    set_pipeline_parameter(c, p.key, v);
    for (const PipelineParameter& q : pipeline_parameters())
      EXPECT_EQ(q.get(c), &q == &p ? v : q.default_value()) << "setting " << p.key << " changed " << q.key;
  }
}

TEST(PipelineParameters, RefusesOutOfRangeAndMalformedNamingTheKey) {
  PipelineConfig c;
  auto message = [&](const std::string& setting) {
    try {
      apply_pipeline_setting(c, setting);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(message("search_downsample=5").find("search_downsample: 5 is not int 1..4"), std::string::npos);
  EXPECT_NE(message("search_downsample=2.5").find("is not int 1..4"), std::string::npos);
  EXPECT_NE(message("max_cost_px=abc").find("max_cost_px 'abc' is not a number"), std::string::npos);
  EXPECT_NE(message("view_stride=two").find("view_stride 'two' is not an integer"), std::string::npos);
  EXPECT_NE(message("trace=2").find("trace: 2 is not bool"), std::string::npos);
  EXPECT_NE(message("sharpness=3").find("unknown key 'sharpness' (keys: "), std::string::npos);
  EXPECT_NE(message("view_stride").find("is not key=value"), std::string::npos);
  EXPECT_EQ(message("trace=true"), "accepted");
  EXPECT_TRUE(c.trace);
  EXPECT_EQ(message("search_polarity_penalty_px=inf"), "accepted");
  EXPECT_TRUE(std::isinf(c.search_polarity_penalty_px));
  EXPECT_EQ(message("edges_high_threshold=1.1"), "accepted");
  EXPECT_FLOAT_EQ(c.depth_edges.high_threshold, 1.1f);

  PipelineConfig bad;
  bad.max_candidates = 0;
  try {
    validate_parameters(bad);
    ADD_FAILURE() << "max_candidates 0 accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("max_candidates = 0 is not int 1..16"), std::string::npos) << e.what();
  }
  PipelineConfig gates;
  gates.fit_inlier_cost_px = 5;  // above the gate of 4
  EXPECT_THROW(validate_parameters(gates), std::invalid_argument);
  PipelineConfig hysteresis;
  hysteresis.depth_edges.low_threshold = 0.9f;  // above the high threshold
  EXPECT_THROW(validate_parameters(hysteresis), std::invalid_argument);
}

// docs/configuration.md holds the table between two marker lines. MFC_UPDATE_DOCS=1 writes it.
TEST(PipelineParameters, ConfigurationDocHoldsTheTable) {
  const std::string path = std::string(MFC_SOURCE_DIR) + "/docs/configuration.md";
  std::ifstream in(path);
  ASSERT_TRUE(in) << path;
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string doc = ss.str();
  const std::string begin = "<!-- vision parameters: begin (made from vision/pipeline/pipeline_parameters.cpp) -->\n";
  const std::string end = "<!-- vision parameters: end -->\n";
  const auto b = doc.find(begin), e = doc.find(end);
  ASSERT_NE(b, std::string::npos) << path << " lacks the line " << begin;
  ASSERT_NE(e, std::string::npos) << path << " lacks the line " << end;
  ASSERT_LT(b, e);
  const std::string want = pipeline_parameters_markdown();
  const std::string have = doc.substr(b + begin.size(), e - b - begin.size());
  if (have != want && std::getenv("MFC_UPDATE_DOCS")) {
    std::ofstream(path) << doc.substr(0, b + begin.size()) << want << doc.substr(e);
    GTEST_SKIP() << "wrote the table into " << path;
  }
  EXPECT_EQ(have, want) << path << " is out of date: run test_vision_pipeline_units with MFC_UPDATE_DOCS=1 to write it";
}

}  // namespace
}  // namespace mfcd::vision
