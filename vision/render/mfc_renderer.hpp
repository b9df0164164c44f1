#pragma once
// Offscreen OpenGL rendering (EGL surfaceless; Mesa llvmpipe when there is no GPU) of
// scenes of part meshes as seen by the multi-flash camera: per pixel, the image lit by
// each of the 8 LEDs with cast shadows, the ambient image, depth along the optical axis
// in mm and which part is visible.

#include "vision/camera/camera.hpp"
#include "vision/camera/mfc_frames.hpp"
#include "vision/model/mesh.hpp"

#include <opencv2/core.hpp>

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <utility>
#include <vector>

namespace mfcd::vision {

// Surface reflectance, from matte (specular = 0) to shiny metal (specular ~ 1, high
// shininess). A painted pattern changes the albedo only: an intensity edge that is not a
// depth edge, which depth-edge extraction must ignore.
struct Material {
  enum class Paint { none, stripes, checker };
  float albedo = 0.7f;
  float diffuse = 1.0f;
  float specular = 0.0f;
  float shininess = 30.0f;  // Blinn-Phong exponent
  Paint paint = Paint::none;
  float paint_period_mm = 6.0f;  // stripe/checker period in the part's own frame
  float paint_albedo = 0.15f;    // albedo of the painted areas

  static Material matte(float albedo = 0.7f) { return {.albedo = albedo}; }
  static Material shiny() { return {.albedo = 0.5f, .diffuse = 0.6f, .specular = 0.8f, .shininess = 60.0f}; }
};

// One part in the scene: p_camera = R * p_mesh + t (mm).
struct ScenePart {
  int mesh_id = -1;  // from MfcRenderer::add_mesh
  cv::Matx33d R = cv::Matx33d::eye();
  cv::Vec3d t_mm{0, 0, 300};
  Material material;
  // False for a surface nothing in the scene lies behind as seen from any LED (a background
  // plane): it is left out of the shadow maps, which changes no pixel and saves filling them.
  bool casts_shadows = true;
};

struct Illumination {
  // Brightness (8-bit grey levels) of a white matte surface facing an LED at the working
  // distance; falls off with the inverse square of the distance to the LED.
  float flash_dn = 170.0f;
  // Ambient light present in every image: uniform part plus a room light from
  // `room_direction` (pointing from the scene to the light, camera frame), no shadows.
  float ambient_dn = 12.0f;
  float room_dn = 18.0f;
  cv::Vec3d room_direction{-0.3, -0.5, -0.8};
};

// Camera sensor noise in grey levels: Gaussian read noise plus shot noise whose variance
// grows linearly with the signal. Seeded so a render is reproducible.
struct SensorNoise {
  bool enabled = true;
  double read_sigma_dn = 1.0;
  double shot_dn_per_electron = 0.05;  // variance of shot noise = this * signal
};

struct RenderOptions {
  // Shadow accuracy only moves the far end of each shadow, never the depth edge itself
  // (the occluding contour), so a map about as fine as the camera's pixels is enough.
  int shadow_map_size = 1024;
  // Depth range of the shadow maps as fractions of the working distance. Parts nearer
  // than the near plane still cast shadows (depth clamp); farther than far ones do not.
  double shadow_near_fraction = 0.4;
  double shadow_far_fraction = 4.0;
  // A render fills only the texels of each map that its window can read (the same values as
  // a whole fill; shadow_footprint.hpp). True fills every texel: the reference for tests.
  bool fill_whole_shadow_maps = false;
  // Light each pixel once, from the nearest surface drawn there (deferred shading): the lit cost
  // is per pixel, not per fragment of every triangle covering it, which llvmpipe pays dearly for
  // the thin triangles of tessellated curves; the same values (tested). False lights every
  // fragment drawn (forward). The teacher turns it on, where its time is measured
  // (docs/template-database.md); other renders keep forward shading for now.
  bool deferred_shading = false;
  Illumination light;
  SensorNoise noise;
};

// How a render is lit, beyond its options: by default every pixel of its region, by the LEDs
// where the configuration puts them.
struct Lighting {
  // The LED ring turned about the optical axis by this angle (rad, from +x towards +y of the
  // camera frame): the light the part gets when it is turned the opposite way under the fixed
  // ring, seen in its own image (no resampling).
  double ring_turn_rad = 0;
  // Only the pixels of the tiles (squares of MfcRenderer::lit_tile_px a side, from the image's
  // corner) that hold a pixel where this image (the current camera's size) is not 0 are lit;
  // the others read as if nothing were there, as pixels outside the region do. The cost of the
  // lighting follows the lit tiles. Null: every pixel. Needs deferred shading.
  const cv::Mat1b* lit = nullptr;
};

struct MfcRender {
  MfcFrames frames;                     // 8 flash images (each includes the ambient light) + ambient
  cv::Mat1f depth_mm;                   // z of the visible surface in the camera frame; 0 where no part
  cv::Mat1b part_index;                 // 0 where no part, k where parts[k - 1] is visible
  std::vector<cv::Mat1f> flash_linear;  // noise-free, unquantised flash images (DN), same order
  cv::Mat1f ambient_linear;
};

class MfcRenderer {
 public:
  // Creates the EGL context and GL resources. Throws std::runtime_error with a clear
  // message when EGL/OpenGL cannot be initialised.
  explicit MfcRenderer(const CameraConfig& config, const RenderOptions& options = {});
  ~MfcRenderer();
  MfcRenderer(const MfcRenderer&) = delete;
  MfcRenderer& operator=(const MfcRenderer&) = delete;

  // Uploads a mesh (normals: smooth within `crease_deg`, sharp across it); returns its id.
  int add_mesh(const Mesh& mesh, double crease_deg = 35.0);

  // Renders with another pinhole (e.g. PinholeCamera::cropped to render only a window
  // around the part); the flash positions stay those of the configuration.
  void set_camera(const PinholeCamera& camera);
  const PinholeCamera& camera() const { return camera_; }
  const CameraConfig& config() const { return config_; }
  const RenderOptions& options() const { return options_; }
  RenderOptions& options() { return options_; }

  // Renders all parts at once. Output images are reallocated only when the size changes. With
  // deferred shading, a render of the same parts from the same camera as the last one, within its
  // region, reuses the surfaces it drew and only lights them again (e.g. with the ring turned).
  // Only the pixels inside `region` (image coordinates; empty = the whole image) are drawn, lit
  // and read back; every other pixel reads as if nothing were there (no part, depth 0, no light
  // before the sensor's noise), and each pixel inside has exactly the values a whole render
  // gives it. For a caller that knows all it needs lies inside: it costs about the region's
  // share of the image.
  // Throws std::invalid_argument for a region outside the image, or a `lighting.lit` mask of
  // another size or without deferred shading.
  void render(std::span<const ScenePart> parts, MfcRender& out, uint64_t noise_seed = 1, cv::Rect region = {},
              const Lighting& lighting = {});
  // Depth and visibility only (no shading, no shadow maps): faster.
  void render_depth(std::span<const ScenePart> parts, cv::Mat1f& depth_mm, cv::Mat1b& part_index);

  // The side (px) of the tiles a Lighting::lit mask lights in an image of `size`: 8, or larger
  // for an image of more than kMaxLitTiles tiles.
  static int lit_tile_px(cv::Size size);
  static constexpr int kMaxLitTiles = 256 * 128;

  // The GL renderer string, e.g. "llvmpipe (LLVM 15.0.6, 256 bits)".
  std::string gl_renderer() const;

 private:
  struct Gl;  // render_gl.hpp
  // Camera-frame depth range (mm) of the parts' bounding boxes, within the camera pass's.
  std::pair<double, double> depth_range(std::span<const ScenePart> parts) const;
  // The shadow maps' texels that pixels of `region` read are filled (all with fill_whole_shadow_maps).
  void draw_shadow_maps(std::span<const ScenePart> parts, const cv::Rect& region,
                        std::span<cv::Matx44d, 8> unit_from_camera);
  void set_lights(unsigned program, std::span<const cv::Matx44d, 8> unit_from_camera);
  // The drawn region's pixels into `out` (sized to the image, zero elsewhere), in linear DN.
  void read_back(const cv::Rect& region, MfcRender& out);
  enum class Shading { none, forward, deferred };  // render_shaders.hpp
  // Whether the deferred surfaces hold `parts` as the current camera sees them, in all of `region`.
  bool surfaces_hold(std::span<const ScenePart> parts, const cv::Rect& region) const;
  // Clears and draws `region` only (a non-empty rectangle of the image); a deferred render whose
  // surfaces are held already (surfaces_hold) only lights them.
  void draw_scene(std::span<const ScenePart> parts, Shading shading, const cv::Rect& region,
                  const cv::Mat1b* lit = nullptr);
  // Draws the parts with `prog`, lit with these shadow maps when given (the forward program).
  void draw_parts(std::span<const ScenePart> parts, unsigned prog, const std::array<cv::Matx44d, 8>* unit_from_camera);
  // The deferred second pass: lights every pixel of the scissor box from the drawn surfaces.
  // `lit`: the pixels lit (Lighting::lit), or null for all; `matte`: every part has specular 0.
  void shade_surfaces(const std::array<cv::Matx44d, 8>& unit_from_camera, const cv::Mat1b* lit, bool matte);
  // Clears the lit target and sets the stencil test to pass only where `lit` is not 0.
  void mark_lit_pixels(const cv::Mat1b& lit);
  // Near and far planes of the camera pass: they only bound what is drawn, as depth is
  // written as camera-frame z in float.
  double camera_near_mm() const { return 1.0; }
  double camera_far_mm() const { return config_.working_distance_mm * 20; }
  // How far a shadow lookup moves along the surface normal against acne, in mm per mm of
  // distance to the LED: about a texel, as a texel seen from the LED spans d / fs mm at d.
  double normal_offset() const { return 1.5 / options_.shadow_map_size; }
  CameraConfig config_;
  // The LEDs of the render under way: the configuration's, turned by Lighting::ring_turn_rad.
  std::array<cv::Vec3d, 8> leds_;
  PinholeCamera camera_;
  RenderOptions options_;
  std::unique_ptr<Gl> gl_;
  std::vector<float> readback_;
  cv::Mat1f noise_;
};

}  // namespace mfcd::vision
