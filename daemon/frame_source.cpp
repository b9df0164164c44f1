#include "daemon/frame_source.hpp"

#include <cmath>
#include <optional>
#include <stdexcept>

#include "daemon/log.hpp"
#include "daemon/rigid_conversions.hpp"
#include "mfcd/hal/aravis_camera.hpp"
#include "mfcd/hal/aravis_strobe_light_ring.hpp"
#include "mfcd/hal/gpiod_light_ring.hpp"
#include "mfcd/hal/rendered_cell_scene.hpp"
#include "mfcd/hal/simulated.hpp"
#include "mfcd/hal/v4l2_camera.hpp"
#include "vision/calib/sim_board.hpp"
#include "vision/camera/camera.hpp"
#include "vision/common/rotation.hpp"
#include "vision/model/mesh.hpp"
#include "vision/render/mfc_renderer.hpp"

namespace mfcd::daemon {

namespace {

hal::GpiodLightRingConfig gpiod_config(const DaemonConfig& c) {
  hal::GpiodLightRingConfig g;
  g.chip = c.lights.chip;
  g.offsets = c.lights.offsets;
  g.active_low = c.lights.active_low;
  return g;
}

hal::V4L2CameraConfig v4l2_config(const DaemonConfig& c, const vision::CameraConfig& model) {
  hal::V4L2CameraConfig v;
  v.device = c.camera.device;
  v.width = model.camera.image_size.width;
  v.height = model.camera.image_size.height;
  v.bits_per_pixel = c.camera.bits_per_pixel;
  v.frame_rate = c.camera.frame_rate;
  v.exposure_us = c.camera.exposure_us;
  if (c.camera.gain) v.gain = static_cast<int>(*c.camera.gain);  // integral: checked by the config
  v.buffer_count = c.camera.buffer_count;
  v.dequeue_timeout = std::chrono::milliseconds(c.camera.dequeue_timeout_ms);
  return v;
}

hal::AravisCameraConfig aravis_config(const DaemonConfig& c, const vision::CameraConfig& model) {
  hal::AravisCameraConfig a;
  a.camera_id = c.camera.device;
  a.width = model.camera.image_size.width;
  a.height = model.camera.image_size.height;
  a.bits_per_pixel = c.camera.bits_per_pixel;
  if (c.camera.exposure_us) a.exposure_us = *c.camera.exposure_us;
  a.gain = c.camera.gain;
  a.buffer_count = c.camera.buffer_count;
  a.frame_timeout = std::chrono::milliseconds(c.camera.dequeue_timeout_ms);
  a.packet_size = c.camera.packet_size;
  if (c.lights.type == LightsType::Camera) {
    hal::CameraStrobeConfig s;
    s.strobe_line = c.lights.strobe_line;
    s.select_lines = c.lights.select_lines;
    s.source = c.lights.strobe_source == StrobeSourceSetting::Timer ? hal::StrobeSource::Timer
                                                                    : hal::StrobeSource::ExposureActive;
    s.pulse_us = c.lights.strobe_pulse_us;
    s.strobe_inverted = c.lights.active_low;
    a.strobe = s;
  }
  return a;
}

// Real devices: a V4L2 or GenICam (Aravis) camera, the LEDs on GPIO lines or on the camera's own
// outputs. The strobe ring borrows the camera: members are destroyed sequencer, ring, camera.
class HardwareFrameSource final : public FrameSource {
 public:
  explicit HardwareFrameSource(const DaemonConfig& c) {
    const vision::CameraConfig model = vision::load_camera_config(c.camera.model);
    if (c.camera.type == CameraType::Aravis) {
      auto aravis = std::make_unique<hal::AravisCamera>(aravis_config(c, model));
      if (c.lights.type == LightsType::Camera) lights_ = std::make_unique<hal::AravisStrobeLightRing>(*aravis);
      camera_ = std::move(aravis);
    } else {
      camera_ = std::make_unique<hal::V4L2Camera>(v4l2_config(c, model));
    }
    if (!lights_) lights_ = std::make_unique<hal::GpiodLightRing>(gpiod_config(c));
    sequencer_ = std::make_unique<hal::MfcSequencer>(
        *camera_, *lights_, hal::SequencerConfig{c.max_stale_frames, static_cast<std::int64_t>(c.settle_us) * 1000});
  }
  void activate() override {
    sequencer_->configure();
    sequencer_->activate();
  }
  void deactivate() noexcept override {
    try {
      sequencer_->deactivate();
    } catch (const std::exception& e) {
      logf(LogLevel::Error, "deactivating %s: %s", describe().c_str(), e.what());
    }
  }
  const hal::FrameSet& capture() override { return sequencer_->read(); }
  hal::ImageFormat format() const override { return camera_->format(); }
  hal::LedMask leds() const override { return lights_->state(); }
  std::string describe() const override { return camera_->describe() + " + " + lights_->describe(); }

 private:
  std::unique_ptr<hal::Camera> camera_;
  std::unique_ptr<hal::LightRing> lights_;
  std::unique_ptr<hal::MfcSequencer> sequencer_;
};

// The simulated cell: a bin of CAD parts lying on the floor at random positions and yaw (fixed
// seed), rendered through SimulatedCamera + SimulatedLightRing by the HAL sequencer. Without any
// recipe mesh it serves the HAL's deterministic test pattern instead (no OpenGL needed).
class SimulatedCellSource final : public FrameSource, public SimulatedWorld {
 public:
  explicit SimulatedCellSource(const DaemonConfig& c)
      : sim_(c.simulation), rng_(c.simulation.seed), flange_T_camera_(c.hand_eye.camera) {
    model_ = vision::load_camera_config(c.camera.model);
    const hal::ImageFormat format{model_.camera.image_size.width, model_.camera.image_size.height, 8};
    for (const auto& r : c.recipes) {
      if (!r.mesh) continue;
      meshes_.push_back({vision::load_mesh(*r.mesh), r.obj_id, -1, 0});
    }
    if (!meshes_.empty() || sim_.plate.enabled) {
      vision::RenderOptions options;
      options.noise.enabled = sim_.noise;
      renderer_ = std::make_unique<vision::MfcRenderer>(model_, options);
      cell_light_ = options.light;
      floor_mesh_ = renderer_->add_mesh(vision::make_plane(4 * sim_.floor_distance_mm));
      for (auto& m : meshes_) {
        m.render_id = renderer_->add_mesh(m.mesh);
        for (const auto& v : m.mesh.vertices) m.radius = std::max(m.radius, std::hypot(double(v[0]), double(v[1])));
      }
      const auto& k = c.calibration;
      plate_ = std::make_unique<vision::calib::SimCalibrationPlate>(
          *renderer_, vision::calib::CheckerBoard{k.board_columns, k.board_rows, k.square_mm});
      cell_ = std::make_unique<hal::RenderedCellScene>(*renderer_, std::vector<vision::ScenePart>{});
      fill_bin();
    }
    camera_ = std::make_unique<hal::SimulatedCamera>(
        hal::SimulatedCameraConfig{format, "sim-cell",
                                   static_cast<std::int64_t>(c.camera.simulated_exposure_us) * 1000},
        lights_, cell_.get());
    sequencer_ = std::make_unique<hal::MfcSequencer>(
        *camera_, lights_, hal::SequencerConfig{c.max_stale_frames, static_cast<std::int64_t>(c.settle_us) * 1000});
  }
  void activate() override {
    sequencer_->configure();
    sequencer_->activate();
  }
  void deactivate() noexcept override {
    try {
      sequencer_->deactivate();
    } catch (const std::exception& e) {
      logf(LogLevel::Error, "deactivating the simulated cell: %s", e.what());
    }
  }
  const hal::FrameSet& capture() override { return sequencer_->read(); }
  hal::ImageFormat format() const override { return camera_->format(); }
  hal::LedMask leds() const override { return lights_.state(); }
  std::string describe() const override {
    return cell_ ? "simulated cell (" + std::to_string(meshes_.size()) + " part types" +
                       (sim_.plate.enabled ? ", calibration plate" : "") + ", " + renderer_->gl_renderer() + ")"
                 : "simulated camera (test pattern)";
  }
  SimulatedWorld* simulation() noexcept override { return this; }
  hal::SimulatedCamera& simulated_camera() override { return *camera_; }
  hal::SimulatedLightRing& simulated_lights() override { return lights_; }
  void truth(SimTruth& out) const override {
    out.count = 0;
    for (const auto& p : bin_) {
      if (out.count == SimTruth::kMaxParts) break;
      const vision::ScenePart seen = in_camera(p.scene, camera_T_laid_);
      out.parts[static_cast<std::size_t>(out.count++)] = {meshes_[p.mesh].obj_id, seen.R, seen.t_mm};
    }
  }
  void move_camera(const Eigen::Isometry3d* base_T_flange) override {
    if (!sim_.eye_in_hand_view || !base_T_flange) return;
    const Eigen::Isometry3d T = camera_from_laid(*base_T_flange);
    if (T.isApprox(camera_T_laid_, 1e-12)) return;
    camera_T_laid_ = T;
    if (cell_ && !plate_shown_) update_scene();
  }
  void remove_picked(const cv::Matx33d& R_seen, const cv::Vec3d& seen,
                     const Eigen::Isometry3d* base_T_flange) override {
    if (!cell_) return;
    held_.reset();
    // Into the frame the bin was laid out in.
    const Eigen::Isometry3d laid_T_camera = sim_.eye_in_hand_view && base_T_flange
                                                ? camera_from_laid(*base_T_flange).inverse()
                                                : Eigen::Isometry3d::Identity();
    const Eigen::Isometry3d estimated = laid_T_camera * to_isometry(R_seen, seen);
    const cv::Vec3d t(estimated.translation().x(), estimated.translation().y(), estimated.translation().z());
    std::size_t best = bin_.size();
    double best_dist = 30.0;  // mm: a pick further than this from every part took nothing
    for (std::size_t i = 0; i < bin_.size(); ++i) {
      const double d = cv::norm(bin_[i].scene.t_mm - t);
      if (d < best_dist) best_dist = d, best = i;
    }
    if (best == bin_.size()) {
      logf(LogLevel::Warning, "simulated cell: the pick at (%.1f, %.1f, %.1f) mm (camera frame) is not on any part",
           t[0], t[1], t[2]);
      return;
    }
    ++taken_;
    if (sim_.gripper_drop_every == 0 || taken_ % static_cast<std::uint64_t>(sim_.gripper_drop_every) != 0)
      held_ = Held{bin_[best].mesh, estimated.inverse() * to_isometry(bin_[best].scene.R, bin_[best].scene.t_mm)};
    bin_.erase(bin_.begin() + static_cast<std::ptrdiff_t>(best));
    if (bin_.empty()) {
      logf(LogLevel::Info, "simulated cell: bin empty, refilling");
      fill_bin();
    } else {
      update_scene();
    }
  }

  void capture_gripper(const vision::PinholeCamera& camera, const Eigen::Isometry3d& camera_T_ideal,
                       cv::Mat1b& out) override {
    if (!cell_) throw std::runtime_error("the simulated camera shows a test pattern: it has no part to hold");
    // What the gripper camera sees behind the part is far away and dark (the paper blurs it away by
    // moving the arm during the exposure).
    std::vector<vision::ScenePart> scene{{floor_mesh_,
                                          cv::Matx33d::eye(),
                                          {0, 0, camera_T_ideal.translation().z() + 600},
                                          vision::Material::matte(0.15f)}};
    if (held_) {
      const Eigen::Isometry3d T = camera_T_ideal * sim_.gripper_slip * held_->estimated_T_true;
      cv::Matx33d R;
      for (int r = 0; r < 3; ++r)
        for (int k = 0; k < 3; ++k) R(r, k) = T.linear()(r, k);
      scene.push_back({meshes_[held_->mesh].render_id,
                       R,
                       {T.translation().x(), T.translation().y(), T.translation().z()},
                       vision::Material::matte(0.75f)});
    }
    renderer_->set_camera(camera);
    try {
      renderer_->render(scene, gripper_render_, ++gripper_seed_);
    } catch (...) {
      renderer_->set_camera(model_.camera);
      throw;
    }
    renderer_->set_camera(model_.camera);
    // A standard camera under the cell's light: the flashes' average.
    cv::Mat1f sum(camera.image_size, 0.f);
    for (const auto& f : gripper_render_.frames.flash) cv::add(sum, f, sum, cv::noArray(), CV_32F);
    sum.convertTo(out, CV_8U, 1.0 / static_cast<double>(gripper_render_.frames.flash.size()));
  }

  void refill() override {
    if (!cell_) return;
    logf(LogLevel::Info, "simulated cell: vision found nothing, refilling the bin");
    fill_bin();
  }

  void show_plate(const PlateRequest& plate) override {
    if (plate.kind == PlateRequest::Kind::None) {
      if (!plate_shown_) return;
      renderer_->options().light = cell_light_;
      plate_shown_ = false;
      update_scene();
      return;
    }
    if (!cell_)
      throw std::runtime_error(
          "the simulated camera shows a test pattern (no recipe meshes, no simulation.calibration_plate): "
          "it cannot show the calibration plate");
    namespace calib = vision::calib;
    const auto matrix = [](const PoseSetting& p) {
      return calib::RobotPose{p.x_mm, p.y_mm, p.z_mm, p.rx_deg, p.ry_deg, p.rz_deg}.matrix();
    };
    const cv::Matx44d given =
        calib::RobotPose{plate.pose[0], plate.pose[1], plate.pose[2], plate.pose[3], plate.pose[4], plate.pose[5]}
            .matrix();
    cv::Matx44d T_camera_board = given;
    if (plate.kind != PlateRequest::Kind::Camera) {
      if (!sim_.plate.enabled)
        throw std::runtime_error(
            "simulation.calibration_plate is not configured: the simulated cell has no true hand-eye "
            "transform to place the plate by the flange pose");
      const auto& t = sim_.plate;
      T_camera_board =
          plate.kind == PlateRequest::Kind::EyeToHand
              ? calib::sim_camera_board(calib::HandEyeMode::eye_to_hand, matrix(t.eye_to_hand_base_T_camera),
                                        matrix(t.eye_to_hand_flange_T_plate), given)
              : calib::sim_camera_board(calib::HandEyeMode::eye_in_hand, matrix(t.eye_in_hand_flange_T_camera),
                                        matrix(t.eye_in_hand_base_T_plate), given);
    }
    // The room light is switched on for calibration: the ambient image (no flash) is the
    // calibration image. The bin is out of the way (the robot holds the plate above it).
    vision::Illumination lit = cell_light_;
    lit.ambient_dn = static_cast<float>(sim_.plate.enabled ? sim_.plate.room_light_dn : 150.0);
    lit.room_dn = 40.0f;
    renderer_->options().light = lit;
    plate_shown_ = true;
    cell_->set_parts(plate_->parts(T_camera_board));
  }

 private:
  struct PartType {
    vision::Mesh mesh;
    int obj_id;
    int render_id;
    double radius;  // largest distance of a vertex from the mesh's z axis
  };
  struct BinPart {
    std::size_t mesh;
    vision::ScenePart scene;
  };
  // The part the robot took last: its type and true pose relative to where vision put it.
  struct Held {
    std::size_t mesh;
    Eigen::Isometry3d estimated_T_true;
  };

  // Parts lie flat (mesh +z towards the camera) at random yaw, spread over the field of view at
  // the floor without overlapping (bounding circles), in the order of the recipes, cycling.
  void fill_bin() {
    bin_.clear();
    if (meshes_.empty()) {  // a cell configured for calibration only: an empty floor
      update_scene();
      return;
    }
    const double f = sim_.floor_distance_mm;
    const double half_w = (model_.camera.image_size.width / 2.0) / model_.camera.fx() * f;
    const double half_h = (model_.camera.image_size.height / 2.0) / model_.camera.fy() * f;
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    for (int k = 0; k < sim_.parts_per_bin; ++k) {
      const std::size_t m = next_++ % meshes_.size();
      const PartType& type = meshes_[m];
      for (int attempt = 0; attempt < 200; ++attempt) {
        const double r = type.radius;
        if (r >= half_w || r >= half_h) break;
        const double x = (2 * unit(rng_) - 1) * (half_w - r), y = (2 * unit(rng_) - 1) * (half_h - r);
        bool overlaps = false;
        for (const auto& p : bin_)
          overlaps = overlaps || std::hypot(p.scene.t_mm[0] - x, p.scene.t_mm[1] - y) < r + meshes_[p.mesh].radius + 2;
        if (overlaps) continue;
        const double yaw = (2 * unit(rng_) - 1) * M_PI;
        // Rz(yaw) * Rx(180): mesh +z points back at the camera.
        const cv::Matx33d R = vision::rotation_about_z(yaw) * cv::Matx33d(1, 0, 0, 0, -1, 0, 0, 0, -1);
        const double zmin = type.mesh.bbox_min()[2];
        bin_.push_back({m, {type.render_id, R, {x, y, f + zmin}, vision::Material::matte(0.75f)}});
        break;
      }
    }
    update_scene();
  }
  void update_scene() {
    std::vector<vision::ScenePart> scene{
        in_camera({floor_mesh_, cv::Matx33d::eye(), {0, 0, sim_.floor_distance_mm}, vision::Material::matte(0.45f)},
                  camera_T_laid_)};
    for (const auto& p : bin_) scene.push_back(in_camera(p.scene, camera_T_laid_));
    cell_->set_parts(std::move(scene));
  }
  // The camera on a flange at base_T_flange, from the camera the bin was laid out for (the one on
  // the flange at simulation.eye_in_hand_view).
  Eigen::Isometry3d camera_from_laid(const Eigen::Isometry3d& base_T_flange) const {
    return (base_T_flange * flange_T_camera_).inverse() * (*sim_.eye_in_hand_view * flange_T_camera_);
  }
  static vision::ScenePart in_camera(vision::ScenePart p, const Eigen::Isometry3d& camera_T_laid) {
    cv::Matx33d R;
    cv::Vec3d t;
    for (int r = 0; r < 3; ++r) {
      for (int k = 0; k < 3; ++k) R(r, k) = camera_T_laid.linear()(r, k);
      t[r] = camera_T_laid.translation()(r);
    }
    p.R = R * p.R;
    p.t_mm = R * p.t_mm + t;
    return p;
  }

  SimulationSettings sim_;
  std::mt19937_64 rng_;
  Eigen::Isometry3d flange_T_camera_;                                // hand_eye.camera (eye-in-hand)
  Eigen::Isometry3d camera_T_laid_ = Eigen::Isometry3d::Identity();  // see move_camera
  vision::CameraConfig model_;
  std::vector<PartType> meshes_;
  std::unique_ptr<vision::MfcRenderer> renderer_;
  int floor_mesh_ = -1;
  std::unique_ptr<hal::RenderedCellScene> cell_;
  std::unique_ptr<vision::calib::SimCalibrationPlate> plate_;
  vision::Illumination cell_light_;
  bool plate_shown_ = false;
  std::vector<BinPart> bin_;
  std::size_t next_ = 0;
  std::optional<Held> held_;
  std::uint64_t taken_ = 0;  // parts the robot took
  vision::MfcRender gripper_render_;
  std::uint64_t gripper_seed_ = 0;
  hal::SimulatedLightRing lights_;
  std::unique_ptr<hal::SimulatedCamera> camera_;
  std::unique_ptr<hal::MfcSequencer> sequencer_;
};

}  // namespace

std::unique_ptr<FrameSource> make_frame_source(const DaemonConfig& config) {
  if (config.camera.type == CameraType::Simulated) {
    if (config.lights.type != LightsType::Simulated)
      throw std::runtime_error(config.source +
                               ": lights.type: a simulated camera needs simulated lights (the camera renders what the "
                               "simulated ring lights)");
    return std::make_unique<SimulatedCellSource>(config);
  }
  if (config.lights.type == LightsType::Simulated)
    throw std::runtime_error(config.source +
                             ": lights.type: a real camera needs real LEDs (gpiod, or camera with camera.type aravis)");
  if (config.lights.type == LightsType::Camera && config.camera.type != CameraType::Aravis)
    throw std::runtime_error(
        config.source +
        ": lights.type: camera fires the LEDs from a GenICam camera's outputs; it needs camera.type: aravis");
  return std::make_unique<HardwareFrameSource>(config);
}

std::string switch_leds_off(const DaemonConfig& config) {
  if (config.lights.type == LightsType::Simulated) return "simulated LEDs: no lines to switch off";
  // The camera's strobe line only lights an LED while the camera exposes, and nothing triggers it
  // once mfcd is gone: no line is left driving an LED.
  if (config.lights.type == LightsType::Camera)
    return "camera strobe outputs: the LEDs light only during an exposure; nothing to switch off";
  hal::GpiodLightRing lights(gpiod_config(config));
  lights.configure();  // requests the lines as outputs, all off; released (still off) at scope end
  return lights.describe() + ": all 8 LED lines driven off";
}

}  // namespace mfcd::daemon
