#include "vision/pipeline/pipeline_parameters.hpp"

#include "vision/pipeline/bin_picking_pipeline.hpp"

#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

namespace mfcd::vision {

namespace {

using Type = PipelineParameter::Type;
constexpr double kInf = std::numeric_limits<double>::infinity();

// Accessors of one field; FIELD(x) for PipelineConfig::x, FIELD(a.b) for a nested one.
#define MFC_FIELD(expr)                                                \
  [](const PipelineConfig& c) { return static_cast<double>(c.expr); }, \
      [](PipelineConfig& c, double v) { c.expr = static_cast<decltype(c.expr)>(v); }
#define MFC_SWITCH(expr) \
  [](const PipelineConfig& c) { return c.expr ? 1.0 : 0.0; }, [](PipelineConfig& c, double v) { c.expr = v != 0; }

// In the order of the pick cycle's stages.
const PipelineParameter kParameters[] = {
    // depth edges (paper Sec. 4.2)
    {"edges_min_flash_dn", Type::number, 0, 255, "DN",
     "pixels whose brightest flash adds less than this over ambient make no edge", true,
     MFC_FIELD(depth_edges.min_flash_dn)},
    {"edges_dim_flash_dn", Type::number, 0, 255, "DN",
     "flash gain below which a pixel's shadow response is weighted down (sensor noise dominates it)", true,
     MFC_FIELD(depth_edges.dim_flash_dn)},
    {"edges_high_threshold", Type::number, 0, 8, "",
     "hysteresis: summed directional shadow response that starts an edge (a clean edge gives about 2)", true,
     MFC_FIELD(depth_edges.high_threshold)},
    {"edges_low_threshold", Type::number, 0, 8, "", "hysteresis: summed response that continues an edge", true,
     MFC_FIELD(depth_edges.low_threshold)},
    // FDCM search (Sec. 3.6, 4.3)
    {"max_cost_px", Type::number, 0.1, 100, "px",
     "search threshold: mean directional chamfer cost under which a placement is a hit", true, MFC_FIELD(max_cost_px)},
    {"search_downsample", Type::integer, 1, 4, "",
     "the search runs on the image reduced by this factor; hypotheses are fitted at full resolution", true,
     MFC_FIELD(search_downsample)},
    {"search_polarity", Type::boolean, 0, 1, "",
     "the search matches a template line only to image edges whose near side is on the same side", true,
     MFC_SWITCH(search_polarity)},
    {"search_polarity_penalty_px", Type::number, 0, kInf, "px",
     "cost of an image edge of the other polarity beyond its orientation difference", true,
     MFC_FIELD(search_polarity_penalty_px)},
    {"template_guides", Type::integer, 1, 8, "",
     "longest template lines slid along the query's lines (the 1-D line search)", true, MFC_FIELD(template_guides)},
    {"query_guides", Type::integer, 1, 1000, "", "longest query lines the template guides slide along", true,
     MFC_FIELD(query_guides)},
    {"max_query_to_guide", Type::number, 1, kInf, "",
     "query lines longer than this times a template's longest guide are not its guides", true,
     MFC_FIELD(max_query_to_guide)},
    {"min_guide_overlap", Type::number, 0, 1, "", "least overlap of a guide pair, of the shorter line", true,
     MFC_FIELD(min_guide_overlap)},
    {"slide_step", Type::integer, 1, 16, "px", "search step along a guide; the best position is then refined", true,
     MFC_FIELD(slide_step)},
    {"view_stride", Type::integer, 1, 64, "",
     "coarse stage searches every n-th template view, the fine stage the views near its best hits", true,
     MFC_FIELD(view_stride)},
    {"coarse_seeds", Type::integer, 0, 64, "",
     "best coarse hits per part type whose neighbouring views the fine stage searches; 0 = coarse only", true,
     MFC_FIELD(coarse_seeds)},
    {"keep_per_view", Type::integer, 1, 16, "", "best placements kept per template view", true,
     MFC_FIELD(keep_per_view)},
    {"keep_separation_px", Type::integer, 0, 1000, "px", "least distance between placements kept of one view", true,
     MFC_FIELD(keep_separation_px)},
    {"share_search_bound", Type::boolean, 0, 1, "",
     "search threads abandon a placement that cannot be among the cycle's best hits so far (faster; the hits then "
     "depend on the threads' timing)",
     true, MFC_SWITCH(share_search_bound)},
    {"search_rounds", Type::integer, 1, PipelineConfig::kMaxSearchRounds, "",
     "search rounds per cycle: a later one searches again without the edges the best candidates explain", true,
     MFC_FIELD(search_rounds)},
    {"round_hypotheses", Type::integer, 1, 1000, "", "new hits a later search round fits", true,
     MFC_FIELD(round_hypotheses)},
    {"round_erase_px", Type::integer, 0, 20, "px",
     "a later round takes out the image edges within this of the best candidates' points", true,
     MFC_FIELD(round_erase_px)},
    {"escalate_below", Type::number, 0, 2, "",
     "a cycle whose best fitted candidate ranks below this searches again over every view; 0 = never, 2 = always", true,
     MFC_FIELD(escalate_below)},
    {"escalate_query_guides", Type::integer, 1, 1000, "", "query guides of the escalation's wide search", true,
     MFC_FIELD(escalate_query_guides)},
    {"escalate_hypotheses", Type::integer, 1, 1000, "", "hits of the wide search fitted and ranked", true,
     MFC_FIELD(escalate_hypotheses)},
    {"escalate_placements_per_view", Type::integer, 1, 16, "", "placements kept per view by the wide search", true,
     MFC_FIELD(escalate_placements_per_view)},
    {"escalate_separation_px", Type::integer, 0, 1000, "px",
     "least distance between the wide search's placements of one view", true, MFC_FIELD(escalate_separation_px)},
    {"escalate_max_cost_px", Type::number, 0, 100, "px", "search threshold of the wide search; 0 = max_cost_px", true,
     MFC_FIELD(escalate_max_cost_px)},
    // 3-D pose from the hypotheses (Sec. 4.4)
    {"fit_hypotheses", Type::boolean, 0, 1, "",
     "hypotheses are fitted in 6-DoF and ranked by the fitted score; 0 = ranked by the search cost", true,
     MFC_SWITCH(fit_hypotheses)},
    {"fit_candidates", Type::integer, 1, 1000, "", "distinct best search hits fitted in 6-DoF (one part type)", true,
     MFC_FIELD(fit_candidates)},
    {"fit_candidates_per_type", Type::integer, 0, 1000, "",
     "hits fitted in addition for each part type a cycle searches beyond the first", true,
     MFC_FIELD(fit_candidates_per_type)},
    {"fit_score_gate_px", Type::number, 0.01, 100, "px",
     "image distance beyond which a model point scores nothing in the fit", true, MFC_FIELD(fit_score_gate_px)},
    {"fit_inlier_cost_px", Type::number, 0.01, 100, "px", "image distance within which a model point is an inlier",
     true, MFC_FIELD(fit_inlier_cost_px)},
    {"edge_polarity", Type::boolean, 0, 1, "",
     "the fit pairs a model point only with an image edge whose near side is the part's", true,
     MFC_SWITCH(edge_polarity)},
    {"unexplained_weight", Type::number, 0, 10, "",
     "rank lost when every image edge inside a fitted outline is left unexplained", true,
     MFC_FIELD(unexplained_weight)},
    {"evidence_weight", Type::number, 0, 1, "",
     "rank gained per unit of ln(edge points found / 300) at the fitted pose", true, MFC_FIELD(evidence_weight)},
    {"rescore_hypotheses", Type::integer, 0, 1000, "",
     "best fitted hypotheses scored again with every point of their view; 0 = off", true,
     MFC_FIELD(rescore_hypotheses)},
    {"depth_starts", Type::integer, 0, 1000, "",
     "best hypotheses fitted again from depth_start_mm further and nearer; 0 = off", true, MFC_FIELD(depth_starts)},
    {"depth_start_mm", Type::number, 0.1, 100, "mm", "depth offset of the depth starts", true,
     MFC_FIELD(depth_start_mm)},
    {"flip_checks", Type::integer, 0, 1000, "", "best hypotheses compared with their turned-over poses; 0 = off", true,
     MFC_FIELD(flip_checks)},
    {"floor_starts", Type::integer, 0, 1000, "",
     "with a known floor, best hypotheses hovering above it fitted again from it; 0 = off", true,
     MFC_FIELD(floor_starts)},
    {"floor_start_height_mm", Type::number, 0, 1000, "mm",
     "how high above the floor a hypothesis may hover and be fitted again from it", true,
     MFC_FIELD(floor_start_height_mm)},
    {"floor_start_min_score_ratio", Type::number, 0, 10, "",
     "share of the free fit's score the floor start's fit needs to be kept", true,
     MFC_FIELD(floor_start_min_score_ratio)},
    {"floor_tolerance_mm", Type::number, 0, 100, "mm",
     "how far a model may reach below the bin floor and still count as on it", true, MFC_FIELD(floor.tolerance_mm)},
    // candidates and refinement (Sec. 4.5)
    {"max_candidates", Type::integer, 1, 16, "", "pick candidates kept per cycle, best first", true,
     MFC_FIELD(max_candidates)},
    {"candidate_overlap", Type::number, 0, 1, "",
     "search boxes overlapping by more than this (IoU) are one part: one candidate, one alternative place", true,
     MFC_FIELD(candidate_overlap)},
    {"alternative_min_differ", Type::number, 0, 1, "",
     "share of edge points a distinct pose (5 mm or 10 degrees away) must also differ in to be the alternative", true,
     MFC_FIELD(alternative_min_differ)},
    {"ambiguous_support", Type::number, -1, 1, "",
     "a candidate whose edges favour it over its alternative by less than this share of their differing points is "
     "ambiguous",
     true, MFC_FIELD(ambiguous_support)},
    // confidence (PoseCandidate::score = 1 / (1 + exp(-logit)), logit = bias + sum of weight x measure)
    {"confidence_bias", Type::number, -100, 100, "", "the confidence model's logit at all measures 0", true,
     MFC_FIELD(confidence.bias)},
    {"confidence_fit_rank", Type::number, -100, 100, "", "logit weight of the fitted rank", true,
     MFC_FIELD(confidence.fit_rank)},
    {"confidence_coverage", Type::number, -100, 100, "", "logit weight of the explained share of image edges", true,
     MFC_FIELD(confidence.coverage)},
    {"confidence_inlier_fraction", Type::number, -100, 100, "", "logit weight of the fit's inlier share", true,
     MFC_FIELD(confidence.inlier_fraction)},
    {"confidence_fit_cost_px", Type::number, -100, 100, "1/px", "logit weight of the fit's mean directional cost", true,
     MFC_FIELD(confidence.fit_cost_px)},
    {"confidence_has_alternative", Type::number, -100, 100, "", "logit added when a distinct alternative was fitted",
     true, MFC_FIELD(confidence.has_alternative)},
    {"confidence_alternative_margin", Type::number, -100, 100, "",
     "logit weight of the fitted rank's lead over the alternative's", true, MFC_FIELD(confidence.alternative_margin)},
    {"confidence_alternative_support", Type::number, -100, 100, "",
     "logit weight of the edges' support for the pose over the alternative, on their differing points", true,
     MFC_FIELD(confidence.alternative_support)},
    {"edge_offset_correction", Type::boolean, 0, 1, "",
     "each candidate's pose polished with the templates' edge offset profiles", true,
     MFC_SWITCH(edge_offset_correction)},
    {"refine_candidates", Type::integer, 0, 64, "",
     "best candidates refined by the render-based refiner; 0 = the fitted pose is kept", true,
     MFC_FIELD(refine_candidates)},
    {"refine_iterations", Type::integer, 0, 1000, "",
     "render-based refinement iterations per refined candidate (fewer near the deadline); 0 = none", true,
     MFC_FIELD(refine_iterations)},
    // the cycle
    {"threads", Type::integer, 0, 256, "",
     "threads of every stage of a cycle; 0 = OpenMP's default (OMP_NUM_THREADS, else every core)", true,
     MFC_FIELD(threads)},
    {"trace", Type::boolean, 0, 1, "", "every fitted hypothesis reported in the result (mfc-eval; allocates per cycle)",
     false, MFC_SWITCH(trace)},
};

#undef MFC_FIELD
#undef MFC_SWITCH

std::string number_text(double v) {
  if (std::isinf(v)) return "inf";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

std::string known_keys() {
  std::string out;
  for (const PipelineParameter& p : kParameters) out += (out.empty() ? "" : ", ") + std::string(p.key);
  return out;
}

}  // namespace

double PipelineParameter::default_value() const {
  static const PipelineConfig defaults;
  return get(defaults);
}

bool PipelineParameter::in_range(double v) const {
  if (!(v >= min && v <= max)) return false;
  return type == Type::number || v == std::floor(v);
}

std::string PipelineParameter::range_text() const {
  switch (type) {
    case Type::boolean:
      return "bool";
    case Type::integer:
      return "int " + number_text(min) + ".." + number_text(max);
    case Type::number:
      break;
  }
  return "number " + number_text(min) + ".." + number_text(max);
}

std::span<const PipelineParameter> pipeline_parameters() { return kParameters; }

const PipelineParameter* find_pipeline_parameter(std::string_view key) {
  for (const PipelineParameter& p : kParameters)
    if (key == p.key) return &p;
  return nullptr;
}

void set_pipeline_parameter(PipelineConfig& config, std::string_view key, double value) {
  const PipelineParameter* p = find_pipeline_parameter(key);
  if (!p) throw std::invalid_argument("unknown key '" + std::string(key) + "' (keys: " + known_keys() + ")");
  if (!p->in_range(value))
    throw std::invalid_argument(std::string(p->key) + ": " + number_text(value) + " is not " + p->range_text());
  p->set(config, value);
}

void apply_pipeline_setting(PipelineConfig& config, std::string_view setting) {
  const auto eq = setting.find('=');
  if (eq == std::string_view::npos) throw std::invalid_argument("'" + std::string(setting) + "' is not key=value");
  const std::string key(setting.substr(0, eq)), text(setting.substr(eq + 1));
  const PipelineParameter* p = find_pipeline_parameter(key);
  if (!p) throw std::invalid_argument("unknown key '" + key + "' (keys: " + known_keys() + ")");
  double value = 0;
  if (p->type == Type::boolean && (text == "true" || text == "false")) {
    value = text == "true" ? 1 : 0;
  } else {
    size_t used = 0;
    try {
      value = text == "inf" ? kInf : std::stod(text, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    const char* kind = p->type == Type::integer   ? "an integer"
                       : p->type == Type::boolean ? "0, 1, true or false"
                                                  : "a number";
    if (text != "inf" && (text.empty() || used != text.size()))
      throw std::invalid_argument(key + " '" + text + "' is not " + kind);
  }
  set_pipeline_parameter(config, key, value);
}

void validate_parameters(const PipelineConfig& config) {
  for (const PipelineParameter& p : kParameters) {
    const double v = p.get(config);
    if (!p.in_range(v))
      throw std::invalid_argument("pipeline: " + std::string(p.key) + " = " + number_text(v) + " is not " +
                                  p.range_text());
  }
  if (config.fit_inlier_cost_px > config.fit_score_gate_px)
    throw std::invalid_argument("pipeline: fit_inlier_cost_px must be <= fit_score_gate_px");
  if (config.depth_edges.low_threshold > config.depth_edges.high_threshold)
    throw std::invalid_argument("pipeline: edges_low_threshold must be <= edges_high_threshold");
}

std::string pipeline_parameters_markdown() {
  std::string out = "| key | type | unit | default | meaning |\n| --- | --- | --- | --- | --- |\n";
  for (const PipelineParameter& p : kParameters) {
    if (!p.cell) continue;
    const double d = p.default_value();
    const std::string def = p.type == Type::boolean ? (d != 0 ? "true" : "false") : number_text(d);
    out += "| `" + std::string(p.key) + "` | " + p.range_text() + " | " + (*p.unit ? p.unit : "") + " | " + def +
           " | " + p.meaning + " |\n";
  }
  return out;
}

}  // namespace mfcd::vision
