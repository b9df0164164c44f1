#pragma once
// Shading across the flashes: what the eight flash images say of a pose beyond its depth edges
// (paper Sec. 4.2 takes only the shadows from them). At a pose the part alone is rendered under
// the same flashes in a window around its projection, and at each pixel inside it the share of
// light each flash gives (its image less the ambient one, over the sum of the eight) is compared
// with the images'. The shares do not depend on the surface's albedo or the camera's gain, only
// on the surface normal and the distances to the flashes: a matte face tilted by 20 degrees
// towards one flash of a 40 mm ring at 300 mm takes ~10 % more of its light than of the opposite
// flash's, while its outline in the edge map hardly changes.
//
// The rendered surface is Lambertian: a shiny part's highlights, and pixels that another part
// covers or shadows, disagree with it, so only the best-agreeing share of pixels is averaged.

#include "vision/camera/camera.hpp"
#include "vision/camera/mfc_frames.hpp"
#include "vision/pose/model_edges.hpp"
#include "vision/pose/rigid_transform.hpp"
#include "vision/render/mfc_renderer.hpp"

#include <opencv2/core.hpp>

#include <vector>

namespace mfcd::vision {

struct ShadingParams {
  int margin_px = 4;  // window margin around the projected bounding box
  // Pixels this near the rendered part's outline are not compared (a pose a pixel off would
  // compare the background's shading with the part's).
  int erode_px = 2;
  // A pixel whose rendered depth steps by more than this to a 4-neighbour lies on a
  // self-occlusion or a crease: not compared (mm).
  float max_step_mm = 1.5f;
  float min_signal_dn = 40.0f;  // the eight (flash - ambient) summed, in the images; darker pixels are not compared
  float saturated_dn = 250.0f;  // a flash image at or above this is clipped there: not compared
  // A pixel where one flash gives less than this share of the brightest flash's light lies in a
  // shadow (cast by the part or, in the images, by another part): not compared.
  float min_flash_ratio = 0.3f;
  // The share of compared pixels, best-agreeing first, whose deviations are averaged.
  double keep_fraction = 0.7;

  void validate() const;  // throws std::invalid_argument naming the field
};

struct ShadingAgreement {
  // RMS over the kept pixels of each flash's share minus the rendered share, relative to an
  // even share (1/8): 0.1 is a flash giving 10 % more or less of its even share than rendered.
  double error = 0;
  int pixels = 0;  // pixels compared (0: the part is not in the image, or nothing lit to compare)
};

// Not thread-safe: it borrows an MfcRenderer (whose GL context belongs to the calling thread) and
// changes its camera to the window it renders. Buffers are reused between calls.
class ShadingCheck {
 public:
  explicit ShadingCheck(MfcRenderer& renderer, const ShadingParams& params = {});

  // `frames` (8 flash images and the ambient one) as seen by `camera`; the part `model` at `m2c`.
  ShadingAgreement compare(const MfcFrames& frames, const PinholeCamera& camera, const PoseModel& model,
                           const RigidTransform& m2c);
  // The same over the whole image, rendered at full size: the reference the windowed compare()
  // must agree with (tests).
  ShadingAgreement compare_whole_image(const MfcFrames& frames, const PinholeCamera& camera, const PoseModel& model,
                                       const RigidTransform& m2c);

 private:
  // The part alone at `m2c` seen by `camera` (the window's or the whole image's) into render_.
  void render_at(const PinholeCamera& camera, const PoseModel& model, const RigidTransform& m2c);
  ShadingAgreement compare_in(const MfcFrames& frames, const cv::Rect& window);

  MfcRenderer& renderer_;
  ShadingParams params_;
  std::vector<ScenePart> scene_;
  MfcRender render_;
  cv::Mat1b mask_;
  std::vector<double> deviations_;
};

}  // namespace mfcd::vision
