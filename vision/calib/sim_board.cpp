#include "vision/calib/sim_board.hpp"

#include <cmath>
#include <stdexcept>

namespace mfcd::vision::calib {

namespace {

// Shifts a mesh so its box spans [lo, hi] (make_box is centred on the origin).
Mesh box_between(const cv::Vec3d& lo, const cv::Vec3d& hi) {
  Mesh m = make_box(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
  const cv::Vec3f c((lo + hi) * 0.5);
  for (auto& v : m.vertices) v += c;
  return m;
}

double round_to(double v, double step) { return std::round(v / step) * step; }

cv::Matx44d sample_board_view(const PinholeCamera& cam, const CheckerBoard& b, double wd, std::mt19937& rng,
                              double max_tilt_deg, double near = 0.8, double far = 1.25) {
  std::uniform_real_distribution<double> u01(0, 1);
  const cv::Vec3d centre((b.columns - 1) * b.square_mm / 2, (b.rows - 1) * b.square_mm / 2, 0);
  for (int attempt = 0; attempt < 1000; ++attempt) {
    const double tilt = max_tilt_deg * std::sqrt(u01(rng)) * CV_PI / 180;  // more tilted views than flat ones
    const double axis = 2 * CV_PI * u01(rng), roll = 2 * CV_PI * (u01(rng) - 0.5);
    const cv::Matx33d R = rotation_from_vector(cv::Vec3d(std::cos(axis), std::sin(axis), 0) * tilt) *
                          rotation_from_vector(cv::Vec3d(0, 0, roll));
    const double d = wd * (near + (far - near) * u01(rng));
    const double u = cam.image_size.width * (0.3 + 0.4 * u01(rng));
    const double v = cam.image_size.height * (0.3 + 0.4 * u01(rng));
    const cv::Vec3d ray((u - cam.cx()) / cam.fx(), (v - cam.cy()) / cam.fy(), 1.0);
    const cv::Matx44d T = make_transform(R, ray * d - R * centre);
    if (plate_fully_visible(cam, b, T)) return T;
  }
  throw std::runtime_error("simulated board: no fully visible pose found (board too large for the camera?)");
}

cv::Matx44d sample_board_view(const SimBoardScene& scene, double wd, std::mt19937& rng, double max_tilt_deg,
                              double near = 0.8, double far = 1.25) {
  return sample_board_view(scene.camera(), scene.board(), wd, rng, max_tilt_deg, near, far);
}

}  // namespace

SimCalibrationPlate::SimCalibrationPlate(MfcRenderer& renderer, const CheckerBoard& board) : board_(board) {
  board_.validate();
  // The renderer's checker paint has squares of one period in the mesh frame with the dark
  // squares where floor(x/p) + floor(y/p) + floor(z/p) is odd. The plate mesh is the board
  // frame shifted by (s, s, 1.5 s): corner lines on multiples of s, the printed face inside
  // the cell floor(z/s) = 1 (never on a cell boundary), and square (0, 0) dark as the board
  // convention asks.
  const double s = board_.square_mm, thick = 2.0;
  const cv::Vec3d shift(s, s, 1.5 * s);
  T_board_plate_ = make_transform(cv::Matx33d::eye(), -shift);
  plate_mesh_ = renderer.add_mesh(
      box_between({0, 0, 1.5 * s}, {(board_.columns + 1) * s, (board_.rows + 1) * s, 1.5 * s + thick}));
  // White backing plate behind, 1.5 squares wider on each side: the quiet zone detectors need.
  const double m = 1.5 * s;
  const cv::Vec3d lo(-s - m, -s - m, thick), hi(board_.columns * s + m, board_.rows * s + m, thick + 3);
  T_board_backing_ = cv::Matx44d::eye();
  backing_mesh_ = renderer.add_mesh(box_between(lo, hi));
}

std::vector<ScenePart> SimCalibrationPlate::parts(const cv::Matx44d& T_camera_board) const {
  std::vector<ScenePart> parts(2);
  const cv::Matx44d Tp = T_camera_board * T_board_plate_, Tb = T_camera_board * T_board_backing_;
  parts[0] = {.mesh_id = plate_mesh_, .R = rotation_of(Tp), .t_mm = translation_of(Tp), .material = {}};
  parts[0].material.albedo = 0.75f;
  parts[0].material.paint = Material::Paint::checker;
  parts[0].material.paint_period_mm = static_cast<float>(board_.square_mm);
  parts[0].material.paint_albedo = 0.12f;
  parts[1] = {.mesh_id = backing_mesh_, .R = rotation_of(Tb), .t_mm = translation_of(Tb), .material = {}};
  parts[1].material.albedo = 0.75f;
  return parts;
}

SimBoardScene::SimBoardScene(const CameraConfig& config, const CheckerBoard& board) : config_(config), board_(board) {
  board_.validate();
  RenderOptions opt;
  opt.light.ambient_dn = 150.0f;  // an evenly lit room: the ambient image is the calibration image
  opt.light.room_dn = 40.0f;
  opt.noise.enabled = true;
  renderer_ = std::make_unique<MfcRenderer>(config_, opt);
  plate_ = std::make_unique<SimCalibrationPlate>(*renderer_, board_);
}

SimBoardScene::~SimBoardScene() = default;

cv::Mat1b SimBoardScene::render(const cv::Matx44d& T_camera_board, uint64_t noise_seed) {
  renderer_->render(plate_->parts(T_camera_board), out_, noise_seed);
  return out_.frames.ambient.clone();
}

std::vector<cv::Point2f> SimBoardScene::project_corners(const cv::Matx44d& T) const {
  std::vector<cv::Point2f> out;
  for (const auto& p : board_.object_points()) {
    const cv::Point2d q = config_.camera.project(transform_point(T, cv::Vec3d(p.x, p.y, p.z)));
    out.emplace_back(static_cast<float>(q.x), static_cast<float>(q.y));
  }
  return out;
}

bool plate_fully_visible(const PinholeCamera& camera, const CheckerBoard& board, const cv::Matx44d& T,
                         double margin_px) {
  const double s = board.square_mm;
  const double x0 = -1.5 * s, y0 = -1.5 * s, x1 = (board.columns + 0.5) * s, y1 = (board.rows + 0.5) * s;
  for (const cv::Vec3d& p : {cv::Vec3d(x0, y0, 0), cv::Vec3d(x1, y0, 0), cv::Vec3d(x0, y1, 0), cv::Vec3d(x1, y1, 0)}) {
    const cv::Vec3d c = transform_point(T, p);
    if (c[2] < 10) return false;
    const cv::Point2d q = camera.project(c);
    if (q.x < margin_px || q.y < margin_px || q.x > camera.image_size.width - 1 - margin_px ||
        q.y > camera.image_size.height - 1 - margin_px)
      return false;
  }
  // Seen from the printed side.
  return rotation_of(T)(2, 2) > 0.3;
}

bool SimBoardScene::fully_visible(const cv::Matx44d& T, double margin_px) const {
  return plate_fully_visible(config_.camera, board_, T, margin_px);
}

std::vector<cv::Matx44d> random_plate_views(const PinholeCamera& camera, const CheckerBoard& board, int count,
                                            double wd, std::mt19937& rng, double max_tilt_deg, double near,
                                            double far) {
  std::vector<cv::Matx44d> v;
  for (int i = 0; i < count; ++i) v.push_back(sample_board_view(camera, board, wd, rng, max_tilt_deg, near, far));
  return v;
}

cv::Matx44d sim_camera_board(HandEyeMode mode, const cv::Matx44d& X, const cv::Matx44d& Y, const cv::Matx44d& F) {
  return mode == HandEyeMode::eye_in_hand ? inverse_transform(X) * inverse_transform(F) * Y
                                          : inverse_transform(X) * F * Y;
}

cv::Matx44d sim_flange_pose(HandEyeMode mode, const cv::Matx44d& X, const cv::Matx44d& Y, const cv::Matx44d& Tcb) {
  return mode == HandEyeMode::eye_in_hand ? Y * inverse_transform(Tcb) * inverse_transform(X)
                                          : X * Tcb * inverse_transform(Y);
}

std::vector<cv::Matx44d> random_board_views(const SimBoardScene& scene, int count, double wd, std::mt19937& rng,
                                            double max_tilt_deg, double near, double far) {
  std::vector<cv::Matx44d> v;
  for (int i = 0; i < count; ++i) v.push_back(sample_board_view(scene, wd, rng, max_tilt_deg, near, far));
  return v;
}

SimHandEyeCell make_sim_hand_eye_cell(const SimBoardScene& scene, HandEyeMode mode, int count, double wd,
                                      std::mt19937& rng) {
  SimHandEyeCell cell;
  cell.mode = mode;
  if (mode == HandEyeMode::eye_in_hand) {
    // Camera beside the tool, looking along the tool axis; board lying on the table, its
    // printed side up (board z pointing down into the table).
    cell.hand_eye_true = make_transform(euler_to_rotation(1.5, -2.0, 90.5), {42.0, -27.5, 95.0});
    cell.board_true = make_transform(euler_to_rotation(180, 0, 12), {450.0, -60.0, 15.0});
  } else {
    // Camera on a gantry looking down; board held by the flange.
    cell.hand_eye_true = make_transform(euler_to_rotation(178.0, 1.0, -88.0), {620.0, 110.0, 950.0});
    cell.board_true = make_transform(euler_to_rotation(0.5, -1.0, 30.0), {-35.0, -20.0, 25.0});
  }
  const cv::Matx44d& X = cell.hand_eye_true;
  const cv::Matx44d& Y = cell.board_true;
  for (int i = 0; i < count; ++i) {
    const cv::Matx44d Tcb = sample_board_view(scene, wd, rng, 35.0);
    const cv::Matx44d F = sim_flange_pose(mode, X, Y, Tcb);
    RobotPose p = RobotPose::from_matrix(F);
    for (double* v : {&p.x_mm, &p.y_mm, &p.z_mm, &p.rx_deg, &p.ry_deg, &p.rz_deg}) *v = round_to(*v, 0.001);
    const cv::Matx44d Fr = p.matrix();
    const cv::Matx44d seen = sim_camera_board(mode, X, Y, Fr);
    cell.views.push_back({p, seen});
  }
  return cell;
}

}  // namespace mfcd::vision::calib
