#pragma once
// A stage of the pick cycle: made once when the pipeline is built, run once per cycle on the
// pipeline's state without allocating. process() runs the stages in order and adds each one's
// time to its StageTimes field. The stages, in cycle order (each made in its own file):
//   depth edges, query lines, distance transforms (query_stages.cpp),
//   search (search_stage.cpp), hypothesis fit (hypothesis_fit.cpp), ranking (ranking.cpp),
//   escalation and later search rounds (search_stage.cpp), candidates (candidates_stage.cpp),
//   refinement and grasp visibility (refinement_stage.cpp).

#include "vision/pipeline/pipeline_state.hpp"

#include <memory>
#include <vector>

namespace mfcd::vision::detail {

// What one cycle hands from stage to stage (the buffers themselves are the pipeline's).
struct CycleContext {
  const MfcFrames* frames = nullptr;
  PipelineResult* out = nullptr;
  BinPickingPipeline::Impl::Cycle cycle;  // obj_id, deadline, lateness flags
  // The query at the search's resolution, and its edge map (distance transforms' input).
  const LineSet* query = nullptr;
  const cv::Mat1b* search_map = nullptr;
};

class Stage {
 public:
  Stage(const char* name, double StageTimes::*time) : name_(name), time_(time) {}
  virtual ~Stage() = default;
  Stage(const Stage&) = delete;
  Stage& operator=(const Stage&) = delete;

  virtual void run(BinPickingPipeline::Impl& pipeline, CycleContext& cycle) = 0;
  const char* name() const { return name_; }
  double StageTimes::*time() const { return time_; }  // the field its time is added to

 private:
  const char* name_;
  double StageTimes::*time_;
};

std::unique_ptr<Stage> make_edges_stage();
std::unique_ptr<Stage> make_lines_stage();
std::unique_ptr<Stage> make_distance_stage();
std::unique_ptr<Stage> make_search_stage();
std::unique_ptr<Stage> make_fit_stage();
std::unique_ptr<Stage> make_ranking_stage();
std::unique_ptr<Stage> make_escalation_stage();
std::unique_ptr<Stage> make_rounds_stage();
std::unique_ptr<Stage> make_candidates_stage();
std::unique_ptr<Stage> make_refinement_stage();
std::unique_ptr<Stage> make_grasp_stage();

}  // namespace mfcd::vision::detail
