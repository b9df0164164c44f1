#include "vision/dataset/bop_results.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <stdexcept>

namespace mfcd::vision {

std::string bop_results_row(const BopResult& r) {
  bool finite = std::isfinite(r.score) && std::isfinite(r.time_s);
  for (double v : r.R.val) finite = finite && std::isfinite(v);
  for (int k = 0; k < 3; ++k) finite = finite && std::isfinite(r.t_mm[k]);
  if (!finite)
    throw std::invalid_argument("BOP result of scene " + std::to_string(r.scene_id) + " image " +
                                std::to_string(r.im_id) + " object " + std::to_string(r.obj_id) +
                                " has a non-finite score, pose or time");
  const cv::Matx33d& R = r.R;
  char row[640];
  std::snprintf(row, sizeof row, "%d,%d,%d,%.6f,%.9f %.9f %.9f %.9f %.9f %.9f %.9f %.9f %.9f,%.4f %.4f %.4f,%.4f\n",
                r.scene_id, r.im_id, r.obj_id, r.score, R(0, 0), R(0, 1), R(0, 2), R(1, 0), R(1, 1), R(1, 2), R(2, 0),
                R(2, 1), R(2, 2), r.t_mm[0], r.t_mm[1], r.t_mm[2], r.time_s);
  return row;
}

std::optional<BopResultsName> parse_bop_results_name(const std::string& file) {
  const std::string name = std::filesystem::path(file).filename().string();
  const std::string stem = name.substr(0, name.find('.'));
  const size_t us = stem.find('_');
  if (us == std::string::npos || us == 0) return std::nullopt;
  // The dataset part ends at the next '_' (an optional id follows it).
  const std::string info = stem.substr(us + 1, stem.find('_', us + 1) - (us + 1));
  const size_t dash = info.find('-');
  if (dash == std::string::npos || dash == 0 || dash + 1 == info.size()) return std::nullopt;
  BopResultsName n;
  n.method = stem.substr(0, us);
  n.dataset = info.substr(0, dash);
  const size_t dash2 = info.find('-', dash + 1);
  n.split = info.substr(dash + 1, dash2 == std::string::npos ? std::string::npos : dash2 - dash - 1);
  if (n.split.empty()) return std::nullopt;
  if (dash2 != std::string::npos) {  // the toolkit takes the third '-' piece; more are ignored
    n.split_type = info.substr(dash2 + 1, info.find('-', dash2 + 1) - (dash2 + 1));
    if (n.split_type.empty()) return std::nullopt;
  }
  return n;
}

}  // namespace mfcd::vision
