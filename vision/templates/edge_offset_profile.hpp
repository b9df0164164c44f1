#pragma once
// Where the depth-edge extractor puts an edge pixel relative to the true occluding outline, as a
// function of the outline's direction in the image.
//
// Why: non-maximum suppression picks one pixel across an edge along the summed normal quantised
// to 45 degrees. Across an edge within ~20 degrees of an image axis it compares the two pixels
// either side of the jump and keeps the occluding one on a tie: those pixels lie 0.2-0.4 px inside
// the outline on average. Across a diagonal edge it compares diagonal neighbours, and the kept
// pixels straddle the outline (~0 px). A template view stores, per point, the offset between its
// detected edge pixel and its model point's projection; when the part turns in the image so that
// an edge that was axis-aligned in the template becomes diagonal, the query's edge lies that much
// further out than the template's offset says, and the fit grows the part, i.e. moves it towards
// the camera. For a plate standing on its rim (a strip ~24 px wide) that is ~2 mm of depth.
// Sensor noise breaks the ties at random and the width of the shadow changes the response, so
// the template renders (noise off) and the query (noise on, parts over a floor) have profiles of
// their own; TemplatePoseFit moves each point by the difference (docs/pose.md, "Edge offset
// profiles").

#include "vision/camera/camera.hpp"
#include "vision/edges/depth_edges.hpp"

#include <vector>

namespace mfcd::vision {

struct EdgeOffsetProfile {
  static constexpr int kBins = 72;  // 5 degrees each, over the full turn (the shadow side matters)
  // Mean signed offset (px) of the detected edge pixels from the outline along the outline's normal
  // into the shadow (positive: further out, away from the part), bin k centred at 5k degrees of
  // that normal's image angle (x right, y down). Empty: no profile (no correction).
  std::vector<float> offset_px;

  bool empty() const { return offset_px.empty(); }
  // Linear interpolation between the bins, periodic; `normal_angle` in radians, any range.
  // 0 when empty.
  double at(double normal_angle) const;
  // Mean of the bins within `half_width_deg` of `centre_deg` + k x 90 degrees, all four quarters
  // (centre 0: the image axes, 45: the diagonals). A summary for reports and tests: one bin holds
  // only a couple of turns, so its value moves with sub-pixel ties that the mean averages out.
  // 0 when empty.
  double mean_near(double centre_deg, double half_width_deg) const;
};

// What a profile is measured under: the template renders' conditions or the query's.
struct EdgeProfileConditions {
  bool noise = true;        // the camera's sensor noise (RenderOptions::noise)
  double floor_gap_mm = 7;  // floor this far below the plate's underside (shadow width)
  int turns = 36;           // in-plane turns of the plate over 90 degrees (each shows 4 sides)
};

// Renders a 40 x 40 x 6 mm plate lying flat `distance_mm` from the camera (its top face) over a
// floor, turned in-plane over 90 degrees (and shifted by fractions of a pixel), with the camera's
// flashes; extracts depth edges with DepthEdgeExtractor(`edges`) and takes, per bin, the mean
// offset of the edge pixels within 2.5 px of each side's projected top-face outline (corners'
// 8 px left out). Throws std::runtime_error when rendering is unavailable or a bin gets fewer
// than 50 pixels.
EdgeOffsetProfile measure_edge_offset_profile(const CameraConfig& camera, double distance_mm,
                                              const EdgeProfileConditions& conditions,
                                              const DepthEdgeParams& edges = {});

}  // namespace mfcd::vision
