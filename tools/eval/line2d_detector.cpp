// LINE-2D (Hinterstoisser et al., OpenCV contrib cv::linemod) as a peer method for Table 1,
// trained on the same template views as FDCM so the comparison is about the matcher.
#include "tools/eval/detectors.hpp"
#include "vision/pose/coarse_pose.hpp"
#include "vision/render/mfc_renderer.hpp"
#include "vision/templates/template_database.hpp"

#include <opencv2/imgproc.hpp>
#include <opencv2/rgbd/linemod.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <stdexcept>

namespace mfcd::eval {

namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

// The image LINE-2D looks at: the per-pixel maximum of the flash images (the part lit from
// every side, shadows filled in), as BGR because cv::linemod's colour gradient takes colour.
void max_image(const vision::MfcFrames& frames, cv::Mat3b& out) {
  cv::Mat m = frames.flash.empty() ? frames.ambient.clone() : frames.flash[0].clone();
  for (size_t i = 1; i < frames.flash.size(); ++i) m = cv::max(m, cv::Mat(frames.flash[i]));
  cv::cvtColor(m, out, cv::COLOR_GRAY2BGR);
}

class Line2dDetector final : public Detector {
 public:
  Line2dDetector(const vision::CameraConfig& camera, const std::vector<std::filesystem::path>& files,
                 const Line2dOptions& options, int max_candidates)
      : camera_(camera), options_(options), max_candidates_(max_candidates) {
    const auto t0 = Clock::now();
    detector_ = cv::linemod::getDefaultLINE();
    vision::RenderOptions ro;
    ro.noise.enabled = false;
    vision::MfcRenderer renderer(camera, ro);
    for (const auto& file : files) {
      Part part;
      part.db = vision::load_template_database(file);
      vision::check_template_camera(part.db, camera, file.string());
      const int mesh = renderer.add_mesh(part.db.mesh);
      const std::string cls = std::to_string(part.db.obj_id);
      // A square window around the principal point (where every view puts the part centre)
      // large enough for the part at any in-plane rotation.
      const auto& K = camera.camera;
      const double r_px = 0.5 * part.db.diameter_mm * K.fx() / (part.db.distance_mm - 0.5 * part.db.diameter_mm);
      std::vector<double> scales;
      for (double d : options.distances_mm) scales.push_back(part.db.distance_mm / d);
      if (scales.empty()) scales.push_back(1.0);
      const double max_scale = *std::max_element(scales.begin(), scales.end());
      const int half = static_cast<int>(std::ceil(r_px * 1.1 * std::max(1.0, max_scale))) + 6;
      const cv::Rect window(cvRound(K.cx()) - half, cvRound(K.cy()) - half, 2 * half + 1, 2 * half + 1);
      renderer.set_camera(K.cropped(window));
      const cv::Point2f origin(static_cast<float>(K.cx() - window.x), static_cast<float>(K.cy() - window.y));
      vision::MfcRender render;
      for (size_t v = 0; v < part.db.views.size(); v += static_cast<size_t>(options.view_stride)) {
        const auto& view = part.db.views[v];
        vision::ScenePart sp;
        sp.mesh_id = mesh;
        sp.R = view.R_m2c;
        sp.t_mm = view.t_m2c_mm;
        renderer.render({&sp, 1}, render);
        cv::Mat3b img;
        max_image(render.frames, img);
        const cv::Mat1b mask = render.part_index > 0;
        for (double scale : scales)
          for (double a = 0; a < 360 - 1e-9; a += options.inplane_step_deg) {
            // cv::getRotationMatrix2D turns x towards -y for positive angles; the placement's
            // angle turns x towards +y (image axes), hence the minus. Scaling about the part
            // centre's image is the view at another distance (to first order, as in the FDCM search).
            const cv::Mat M = cv::getRotationMatrix2D(origin, -a, scale);
            cv::Mat3b ri;
            cv::Mat1b rm;
            cv::warpAffine(img, ri, M, img.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT);
            cv::warpAffine(mask, rm, M, mask.size(), cv::INTER_NEAREST, cv::BORDER_CONSTANT);
            cv::Rect bb;
            const int id = detector_->addTemplate({ri}, cls, rm, &bb);
            if (id < 0) continue;  // too few gradient features (a nearly edge-on view)
            meta_[{cls, id}] = {static_cast<int>(v), a * CV_PI / 180, scale,
                                cv::Point2f(origin.x - bb.x, origin.y - bb.y), parts_.size()};
            ++templates_;
          }
      }
      parts_.push_back(std::move(part));
    }
    setup_s_ = std::chrono::duration<double>(Clock::now() - t0).count();
    std::fprintf(stderr,
                 "mfc-eval: LINE-2D trained %d templates (step %.0f deg, view stride %d, %zu distances) in %.1f s\n",
                 templates_, options.inplane_step_deg, options.view_stride,
                 std::max<size_t>(1, options.distances_mm.size()), setup_s_);
  }

  std::string name() const override { return "line2d"; }
  void set_floor_mm(double distance_mm) override {
    vision::BinFloor floor = options_.floor;
    floor.distance_mm = distance_mm;
    floor.validate();
    options_.floor = floor;
  }
  double setup_seconds() const override { return setup_s_; }
  int templates() const { return templates_; }

  void detect(const vision::MfcFrames& frames, int obj_id, Detection& out) override {
    const auto t0 = Clock::now();
    out.estimates.clear();
    out.times = {};
    max_image(frames, query_);
    out.times.edges_ms = ms_since(t0);
    const auto t1 = Clock::now();
    std::vector<cv::String> classes;
    if (obj_id != 0) classes.push_back(std::to_string(obj_id));
    matches_.clear();
    detector_->match({query_}, options_.min_similarity, matches_, classes);
    out.times.search_ms = ms_since(t1);
    const auto t2 = Clock::now();
    // Best first (cv::linemod sorts by similarity); one estimate per place in the image.
    std::vector<cv::Point2f> taken;
    for (const auto& m : matches_) {
      if (static_cast<int>(out.estimates.size()) >= max_candidates_) break;
      const Meta& meta = meta_.at({m.class_id, m.template_id});
      const Part& part = parts_[meta.part];
      const cv::Point2f origin(m.x + meta.offset.x, m.y + meta.offset.y);
      bool near = false;
      for (const auto& p : taken)
        near = near || cv::norm(p - origin) < 0.25 * part.db.diameter_mm * camera_.camera.fx() / part.db.distance_mm;
      if (near) continue;
      taken.push_back(origin);
      vision::TemplatePlacement pl;
      pl.view = meta.view;
      pl.angle_rad = meta.angle_rad;
      pl.scale = meta.scale;
      pl.origin_px = origin;
      vision::RigidPose pose = vision::coarse_pose(part.db, pl, camera_.camera);
      pose = options_.floor.onto_if_below(part.db.mesh, pose, part.db.center_mm);
      out.estimates.push_back({part.db.obj_id, pose.R, pose.t_mm, m.similarity / 100.0, 0, 0, 1, {}});
    }
    out.times.pose_ms = ms_since(t2);
    out.times.total_ms = ms_since(t0);
  }

 private:
  struct Part {
    vision::TemplateDatabase db;
  };
  struct Meta {
    int view = 0;
    double angle_rad = 0;
    double scale = 1;
    cv::Point2f offset;  // part centre's image minus the template's top-left corner
    size_t part = 0;
  };
  vision::CameraConfig camera_;
  Line2dOptions options_;
  int max_candidates_;
  cv::Ptr<cv::linemod::Detector> detector_;
  std::vector<Part> parts_;
  std::map<std::pair<std::string, int>, Meta> meta_;
  int templates_ = 0;
  double setup_s_ = 0;
  cv::Mat3b query_;
  std::vector<cv::linemod::Match> matches_;
};

}  // namespace

std::unique_ptr<Detector> make_line2d_detector(const vision::CameraConfig& camera,
                                               const std::vector<std::filesystem::path>& templates,
                                               const Line2dOptions& options, int max_candidates) {
  return std::make_unique<Line2dDetector>(camera, templates, options, max_candidates);
}

}  // namespace mfcd::eval
