#pragma once
// A part type as the pipeline searches it: its template database and everything made from it once
// at load (the search's digitised templates, the fine stage's view neighbours, the turn checks).

#include "vision/camera/camera.hpp"
#include "vision/model/symmetry_group.hpp"
#include "vision/pipeline/bin_picking_pipeline.hpp"
#include "vision/pipeline/turn_checks.hpp"
#include "vision/search/oriented_template.hpp"
#include "vision/templates/template_database.hpp"

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace mfcd::vision::detail {

// A part type: its database and, per view, the view's lines under every in-plane rotation and
// scale of the search, digitised once at load (the search itself then only slides them).
struct PartModel {
  TemplateDatabase db;
  std::string file;
  std::vector<Warp> warps;
  std::vector<std::vector<OrientedTemplate>> oriented;  // [view][warp]
  // Per view, the other views whose direction lies within the fine stage's radius
  // (symmetry-aware), nearest first.
  std::vector<std::vector<int>> neighbours;
  std::vector<uint8_t> searched;  // per view, this cycle
  // Its exact symmetries from the mesh (db.turns): which two fitted poses are one answer.
  SymmetryGroup symmetries;
  // The turns its leading hypotheses are checked against (turn_checks.hpp).
  using Turn = PoseTurn;
  std::vector<Turn> flips;
  // The normal of a plate with a 2-fold turn about it (plate_axis, model frame): the spin check's.
  std::optional<cv::Vec3d> plate_axis;
};

// Loads a template file for `config`: checked against the camera (std::runtime_error naming the
// file), its lines without polarity unless the search uses it, digitised for every warp of the
// search (config.distances_mm, at config.search_downsample), with its view neighbours for
// config.view_stride; its turns are left to find_turns.
PartModel load_part_model(const std::filesystem::path& file, const CameraConfig& camera, const PipelineConfig& config);

// Every part's turns (PartModel::flips: mesh_turns, then plate_turns), the parts shared out among
// `threads` threads (<= 0: OpenMP's default).
void find_turns(std::vector<PartModel>& parts, int threads);

// Angle between two viewing directions of a part, the smallest over the copies under `sym` (the
// views' fold: views a coarser symmetry would call the same still show different edges).
double view_angle(const PartSymmetry& sym, const cv::Vec3d& a, const cv::Vec3d& b);

// The fine stage's neighbours of every view within its radius for `stride`, nearest first.
std::vector<std::vector<int>> view_neighbours(const TemplateDatabase& db, int stride);

}  // namespace mfcd::vision::detail
