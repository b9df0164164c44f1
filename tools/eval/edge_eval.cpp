// mfc-eval edges: the depth-edge extractor against each image's ground-truth depth.
#include "tools/eval/edge_eval.hpp"

#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "tools/eval/detectors.hpp"
#include "vision/dataset/bop_dataset.hpp"
#include "vision/edges/depth_edges.hpp"
#include "vision/edges/edge_evaluation.hpp"
#include "vision/pipeline/bin_picking_pipeline.hpp"

namespace mfcd::eval {

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// Pixels of `a` within `tolerance_px` of a pixel of `b`.
cv::Mat1b near_to(const cv::Mat1b& a, const cv::Mat1b& b, double tolerance_px) {
  cv::Mat1f to_b;
  cv::distanceTransform(255 - b, to_b, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  return a & (to_b <= static_cast<float>(tolerance_px + 1e-6));
}

// Truth jumps grey, creases dark blue, detected pixels on a truth edge green, the others red.
void write_overlay(const fs::path& file, const cv::Mat1b& detected, const cv::Mat1b& jumps, const cv::Mat1b& creases,
                   double tolerance_px) {
  cv::Mat3b img(detected.size(), cv::Vec3b(0, 0, 0));
  img.setTo(cv::Vec3b(90, 90, 90), jumps);
  img.setTo(cv::Vec3b(110, 40, 0), creases);
  const cv::Mat1b right = near_to(detected, jumps | creases, tolerance_px);
  img.setTo(cv::Vec3b(0, 0, 255), detected & ~right);
  img.setTo(cv::Vec3b(0, 220, 0), right);
  if (!cv::imwrite(file.string(), img)) throw std::runtime_error(file.string() + ": cannot write the overlay");
}

}  // namespace

int run_edge_eval(const EdgeEvalOptions& o) {
  vision::PipelineConfig config;
  for (const auto& s : o.pipeline_settings) apply_eval_setting(config, s);
  const vision::BopDataset data(o.dataset, o.split);
  if (!o.overlay.empty()) fs::create_directories(o.overlay);
  json images = json::array();
  long detected = 0, right = 0, jumps_total = 0, jumps_found = 0;
  int n = 0;
  for (int scene : data.scenes()) {
    for (int image : data.images(scene)) {
      if (o.max_images > 0 && n >= o.max_images) break;
      ++n;
      const vision::BopSceneCamera cam = data.camera(scene, image);
      const vision::CameraConfig camera = cam.config();
      vision::DepthEdgeExtractor extractor(camera.camera, camera.flashes, config.depth_edges);
      vision::DepthEdges edges;
      extractor.extract(data.frames(scene, image), edges);
      const cv::Mat1f depth = data.depth_mm(scene, image);
      const cv::Mat1b jumps = vision::depth_discontinuities(depth, static_cast<float>(o.min_jump_mm));
      const cv::Mat1b creases =
          vision::depth_creases(depth, cam.K, static_cast<float>(o.crease_deg), static_cast<float>(o.min_jump_mm));
      const vision::EdgeScore p = vision::score_edges(edges.edges, jumps | creases, o.tolerance_px);
      const vision::EdgeScore r = vision::score_edges(edges.edges, jumps, o.tolerance_px);
      detected += p.detected;
      right += std::lround(p.precision * p.detected);
      jumps_total += r.truth;
      jumps_found += std::lround(r.recall * r.truth);
      images.push_back({{"scene", scene},
                        {"image", image},
                        {"detected_px", p.detected},
                        {"jump_px", r.truth},
                        {"precision", p.precision},
                        {"recall", r.recall}});
      if (!o.quiet)
        std::printf("scene %3d image %2d  detected %6d  jumps %6d  precision %.3f  recall %.3f\n", scene, image,
                    p.detected, r.truth, p.precision, r.recall);
      if (!o.overlay.empty()) {
        char name[64];
        std::snprintf(name, sizeof name, "edges_s%d_i%d.png", scene, image);
        write_overlay(o.overlay / name, edges.edges, jumps, creases, o.tolerance_px);
      }
    }
  }
  if (n == 0) throw std::runtime_error(o.dataset.string() + ": no image in split '" + o.split + "'");
  const double precision = detected ? double(right) / double(detected) : 0;
  const double recall = jumps_total ? double(jumps_found) / double(jumps_total) : 0;
  std::printf("edges over %d images: precision %.3f (%ld of %ld detected px), recall %.3f (of %ld jump px)\n", n,
              precision, right, detected, recall, jumps_total);
  const json out = {{"dataset", o.dataset.string()},
                    {"split", o.split},
                    {"min_jump_mm", o.min_jump_mm},
                    {"crease_deg", o.crease_deg},
                    {"tolerance_px", o.tolerance_px},
                    {"settings", o.pipeline_settings},
                    {"precision", precision},
                    {"recall", recall},
                    {"detected_px", detected},
                    {"jump_px", jumps_total},
                    {"images", images}};
  std::ofstream f(o.out);
  f << out.dump(1) << '\n';
  f.close();
  if (!f) throw std::runtime_error(o.out.string() + ": cannot write");
  return 0;
}

}  // namespace mfcd::eval
