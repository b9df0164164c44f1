#pragma once
// Builds a part's template database (paper Sec. 4.3): for each out-of-plane rotation the part
// is placed with its bounding-box centre on the optical axis at the working distance, in front
// of a matte background plane that catches its shadows, rendered with the same simulated flashes
// as the real cell, reduced to depth edges by the same DepthEdgeExtractor and line-fitted by the
// same fitter the query goes through. Every edge pixel is traced back to the model point it
// images (the near side of the depth discontinuity in the depth buffer).

#include "vision/edges/depth_edges.hpp"
#include "vision/lines/line_fitter.hpp"
#include "vision/render/mfc_renderer.hpp"
#include "vision/templates/edge_offset_profile.hpp"
#include "vision/templates/template_database.hpp"

#include <functional>
#include <optional>

namespace mfcd::vision {

struct TeachParams {
  int sphere_samples = 300;  // K, over the whole sphere (docs/template-database.md)
  PartSymmetry symmetry;     // the part's: what counts as the same pose
  // The symmetry the views are folded by, when the part's edges break `symmetry` (a feature too
  // small to grip by, e.g. the knob's pointer groove): one of its subgroups. Unset: `symmetry`.
  std::optional<PartSymmetry> views_symmetry;
  double distance_mm = 0;         // part centre to lens; 0 = the camera's working distance
  double background_gap_mm = 15;  // background plane this far behind the part's far side
  int min_edge_pixels = 30;       // views with fewer depth-edge pixels are dropped (degenerate)
  // Edges that depend on where the LEDs stand around the part. A fold between a face facing the
  // camera and one seen at a grazing angle is found for some turns of the part about the line of
  // sight relative to the LED ring and not for others, and the query's part lies at any turn.
  // Each view is rendered `lighting_turns` times, with the LED ring turned about the optical axis
  // by k / lighting_turns of its period (k = 0 is the view itself; turning the ring one way is
  // turning the part the other), and an edge pixel of the view is kept when at least
  // `lighting_min_turns` of those renders show an edge within `lighting_tolerance_px`. 1 turn =
  // off. Four turns, all needed, measured best (docs/pose-experiments.md, "Session 30"). A turned
  // render lights only the pixels within `lighting_band_px` of the view's edges (0 = every
  // pixel): wider than the tolerance plus the extractor's 3x3 reach, so that what the band cuts
  // off cannot reach an edge it checks.
  int lighting_turns = 4;
  int lighting_min_turns = 4;
  int lighting_tolerance_px = 1;
  int lighting_band_px = 6;
  // Each render draws only the box that can hold the part and its shadows (part_region) and
  // leaves the rest of the window empty, which gives every edge the whole window's render gives
  // (tested). True renders the whole window: the reference for tests.
  bool render_whole_window = false;
  int threads = 0;      // rendering threads, each with its own GL context; 0 = cores
  LineFitParams lines;  // `oriented` is always set: templates carry edge polarity
  DepthEdgeParams edges;
  // Measure the extractor's edge offset profiles (EdgeOffsetProfile) for the views' rendering
  // conditions and for the query's, stored with the views; ~4 s more per part.
  bool edge_offset_profiles = true;
  EdgeProfileConditions query_conditions;  // sensor noise on, parts ~7 mm above what is behind them
};

// Called after each view with (views done, views total); may be called from worker threads
// but never concurrently.
using TeachProgress = std::function<void(int done, int total)>;

// Throws std::runtime_error (rendering unavailable) or std::invalid_argument (bad params).
TemplateDatabase teach_templates(const Mesh& mesh, const CameraConfig& camera, const std::string& part_name, int obj_id,
                                 const TeachParams& params, const TeachProgress& progress = {});

// The part centre used for the views (bounding-box centre) and the radius of the sphere
// around it that holds the part.
cv::Vec3d part_center(const Mesh& mesh);
double part_radius(const Mesh& mesh, const cv::Vec3d& center);
// Largest distance between two vertices (BOP "diameter"), exact over the convex hull.
double mesh_diameter(const Mesh& mesh);

}  // namespace mfcd::vision
