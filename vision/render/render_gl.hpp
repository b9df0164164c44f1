#pragma once
// The OpenGL objects of one MfcRenderer (internal to vision/render): its context, programs,
// render targets, shadow maps and uploaded meshes, made together and destroyed together, the
// context last.

#include "vision/model/mesh.hpp"
#include "vision/render/egl_context.hpp"
#include "vision/render/mfc_renderer.hpp"

#define GL_GLEXT_PROTOTYPES 1
#include <GL/gl.h>
#include <GL/glext.h>

#include <opencv2/core.hpp>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace mfcd::vision {

// Throws std::runtime_error("renderer: " + what).
[[noreturn]] void gl_fail(const std::string& what);

struct MfcRenderer::Gl {
  static constexpr int kFlashes = 8;  // layers of the shadow map array

  // Makes the context and every program, and the shadow maps of `shadow_map_size` texels a side.
  // Throws std::runtime_error when OpenGL refuses.
  explicit Gl(int shadow_map_size);
  ~Gl();
  Gl(const Gl&) = delete;
  Gl& operator=(const Gl&) = delete;

  EglContext context;  // first member: made before and destroyed after every GL object below
  GLuint scene_program = 0, depth_program = 0, shadow_program = 0, surface_program = 0;
  // The deferred second pass (render_shaders.hpp): [0] any material, [1] every part matte.
  std::array<GLuint, 2> shade_programs{};
  GLuint lit_mask_program = 0;      // Lighting::lit into the stencil
  std::vector<uint32_t> lit_tiles;  // its uniform: one bit per tile, row-major
  GLuint shadow_tex = 0, shadow_fbo = 0;
  GLuint fbo = 0, depth_rb = 0;
  std::array<GLuint, 3> color_tex{};
  // The deferred pass's surfaces, sharing depth_rb; made by the first deferred render of a size.
  GLuint surface_fbo = 0;
  std::array<GLuint, 3> surface_tex{};  // position/id, normal/albedo, material
  GLuint empty_vao = 0;                 // the full-screen triangle has no vertex data
  cv::Size fbo_size{0, 0};
  // What the deferred surfaces hold: the parts of the last deferred render, through the camera
  // matrix `K`, drawn in `region`; empty until the first.
  struct DrawnSurfaces {
    std::vector<ScenePart> parts;
    cv::Matx33d K;
    cv::Rect region;
  } surfaces_drawn;

  struct GpuMesh {
    GLuint vao = 0, vbo = 0;
    GLsizei vertex_count = 0;
    cv::Vec3f lo, hi;  // bounding box in the mesh's own frame, mm
  };
  std::vector<GpuMesh> meshes;

  void make_current() const { context.make_current(); }
  // The render targets for images of `size` (made again when it changes); the deferred
  // surfaces follow at the first deferred render (ensure_surfaces).
  void ensure_targets(cv::Size size);
  void ensure_surfaces();
  // Uploads interleaved position/normal floats (6 per corner, 3 corners per triangle of
  // `mesh`); returns the mesh id.
  int upload_mesh(const std::vector<float>& data, const Mesh& mesh);

 private:
  // Three RGBA32F attachments of `size`, read texel by texel, and the shared depth-stencil buffer.
  void make_target(GLuint& target, std::array<GLuint, 3>& tex, cv::Size size) const;
};

}  // namespace mfcd::vision
