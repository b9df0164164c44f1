// TemplatePoseFit::fit_two_views: the hypothesis fit over two images (template_pose_fit.hpp).
#include "vision/pose/template_pose_fit.hpp"

namespace mfcd::vision {

TemplatePoseFit::TwoViewResult TemplatePoseFit::fit_two_views(const TemplateDatabase& db, const RigidPose& initial,
                                                              const PinholeCamera& camera,
                                                              const TemplatePoseFit& second,
                                                              const RigidTransform& motion, Workspace& ws,
                                                              Workspace& ws_second) const {
  // The pose lives in the first camera's frame; the second sees motion * pose. Each image uses
  // the template view nearest to how it sees the part, as a symmetric copy S of the pose
  // (nearest_view): the second's pose is motion * pose * S, S fixed until that view changes.
  auto second_pose = [&](const RigidPose& p, const RigidTransform& S) {
    return RigidPose{motion.R * p.R * S.R, motion.R * (p.R * S.t + p.t_mm) + motion.t};
  };
  auto choose_views = [&](const RigidPose& p, int& v1, RigidPose& p1, int& v2, RigidTransform& S) {
    p1 = p;
    v1 = nearest_view(db, camera, p1);
    RigidPose seen{motion.R * p1.R, motion.R * p1.t_mm + motion.t};
    const RigidPose plain = seen;
    v2 = nearest_view(db, camera, seen);
    S = {plain.R.t() * seen.R, plain.R.t() * (seen.t_mm - plain.t_mm)};
  };
  RigidPose pose;
  RigidTransform S;
  int v1 = -1, v2 = -1;
  choose_views(initial, v1, pose, v2, S);
  load_view(db, v1, camera, ws);
  second.load_view(db, v2, camera, ws_second);
  const int steps = params_.iterations;
  int taken = 0;
  for (int it = 0; it < steps; ++it) {
    const double gate = gate_at(it);
    const cv::Vec3d centre = pose.R * db.center_mm + pose.t_mm;
    cv::Matx66d H = cv::Matx66d::zeros();
    cv::Vec6d g(0, 0, 0, 0, 0, 0);
    int n = accumulate(db, v1, pose, centre, camera, gate, ws, nullptr, H, g);
    n +=
        second.accumulate(db, v2, second_pose(pose, S), motion.apply(centre), camera, gate, ws_second, &motion.R, H, g);
    if (n < params_.min_correspondences) break;
    cv::Vec6d delta;
    if (!solve_step(H, g, delta)) break;
    pose = apply_pose_update(pose, db.center_mm, delta);
    taken = it + 1;
    const int old1 = v1, old2 = v2;
    choose_views(pose, v1, pose, v2, S);
    if (v1 != old1) load_view(db, v1, camera, ws);
    if (v2 != old2) second.load_view(db, v2, camera, ws_second);
  }
  TwoViewResult out{evaluate(db, v1, pose, camera, ws),
                    second.evaluate(db, v2, second_pose(pose, S), camera, ws_second)};
  out.first.iterations = out.second.iterations = taken;
  return out;
}

}  // namespace mfcd::vision
