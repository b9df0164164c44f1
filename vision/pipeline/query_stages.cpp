// The query of a cycle: depth edges from the flash images (paper Sec. 4.2), their lines
// (Sec. 3.3) and the distance transforms the search scores with (DT3/IDT3, Sec. 3.4-3.5; the
// baselines' chamfer costs instead).
#include "vision/pipeline/stage.hpp"

namespace mfcd::vision::detail {

namespace {

class EdgesStage final : public Stage {
 public:
  EdgesStage() : Stage("edges", &StageTimes::edges_ms) {}
  void run(BinPickingPipeline::Impl& m, CycleContext& c) override {
    m.extractor.extract(*c.frames, m.edges);
    m.fitter_prepared = false;
  }
};

class LinesStage final : public Stage {
 public:
  LinesStage() : Stage("lines", &StageTimes::lines_ms) {}
  void run(BinPickingPipeline::Impl& m, CycleContext& c) override {
    m.line_fitter.fit(m.edges.edges, &m.edges.direction, m.lines, m.dt3_params.oriented ? &m.edges.shadow : nullptr);
    c.out->edge_pixels = m.lines.inputEdgePixels;
    c.out->query_lines = static_cast<int>(m.lines.set.lines.size());
  }
};

class DistanceStage final : public Stage {
 public:
  DistanceStage() : Stage("distance", &StageTimes::distance_ms) {}
  void run(BinPickingPipeline::Impl& m, CycleContext& c) override {
    const auto [query, search_map] = m.search_query(m.lines);
    c.query = query;
    c.search_map = search_map;
    if (c.cycle.fdcm) {
      m.dt3.compute(*search_map, m.search_dt3);
      m.idt.compute(m.dt3);
    } else {
      m.chamfer.compute(*search_map, m.search_dt3);
    }
  }
};

}  // namespace

std::unique_ptr<Stage> make_edges_stage() { return std::make_unique<EdgesStage>(); }
std::unique_ptr<Stage> make_lines_stage() { return std::make_unique<LinesStage>(); }
std::unique_ptr<Stage> make_distance_stage() { return std::make_unique<DistanceStage>(); }

}  // namespace mfcd::vision::detail
