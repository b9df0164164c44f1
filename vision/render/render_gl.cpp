#include "vision/render/render_gl.hpp"

#include "vision/render/render_shaders.hpp"

#include <initializer_list>
#include <stdexcept>

namespace mfcd::vision {

void gl_fail(const std::string& what) { throw std::runtime_error("renderer: " + what); }

namespace {

// One stage from its source pieces, in order.
GLuint compile(GLenum type, std::initializer_list<const char*> pieces) {
  GLuint s = glCreateShader(type);
  glShaderSource(s, static_cast<GLsizei>(pieces.size()), pieces.begin(), nullptr);
  glCompileShader(s);
  GLint ok = 0;
  glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    std::string log(4096, '\0');
    glGetShaderInfoLog(s, static_cast<GLsizei>(log.size()), nullptr, log.data());
    gl_fail("shader compile failed: " + log);
  }
  return s;
}

GLuint link(std::initializer_list<const char*> vs, std::initializer_list<const char*> fs) {
  GLuint p = glCreateProgram();
  GLuint v = compile(GL_VERTEX_SHADER, vs), f = compile(GL_FRAGMENT_SHADER, fs);
  glAttachShader(p, v);
  glAttachShader(p, f);
  glLinkProgram(p);
  glDeleteShader(v);
  glDeleteShader(f);
  GLint ok = 0;
  glGetProgramiv(p, GL_LINK_STATUS, &ok);
  if (!ok) {
    std::string log(4096, '\0');
    glGetProgramInfoLog(p, static_cast<GLsizei>(log.size()), nullptr, log.data());
    gl_fail("shader link failed: " + log);
  }
  return p;
}

}  // namespace

MfcRenderer::Gl::Gl(int shadow_map_size) {
  make_current();
  using namespace shaders;
  scene_program = link({kVersion, kSceneVs}, {kVersion, kLighting, kSurface, kSceneFs});
  depth_program = link({kVersion, kSceneVs}, {kVersion, kDepthFs});
  shadow_program = link({kVersion, kShadowVs}, {kVersion, kShadowFs});
  surface_program = link({kVersion, kSceneVs}, {kVersion, kSurface, kSurfaceFs});
  shade_programs[0] = link({kVersion, kFullScreenVs}, {kVersion, kLighting, kShadeFs});
  shade_programs[1] = link({kVersion, kFullScreenVs}, {kVersion, kMatte, kLighting, kShadeFs});
  lit_mask_program = link({kVersion, kFullScreenVs}, {kVersion, kLitMaskFs});
  glGenVertexArrays(1, &empty_vao);

  const int S = shadow_map_size;
  glGenTextures(1, &shadow_tex);
  glBindTexture(GL_TEXTURE_2D_ARRAY, shadow_tex);
  glTexImage3D(GL_TEXTURE_2D_ARRAY, 0, GL_DEPTH_COMPONENT32F, S, S, kFlashes, 0, GL_DEPTH_COMPONENT, GL_FLOAT, nullptr);
  glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_COMPARE_MODE, GL_COMPARE_REF_TO_TEXTURE);
  glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_COMPARE_FUNC, GL_LEQUAL);
  glGenFramebuffers(1, &shadow_fbo);
  if (glGetError() != GL_NO_ERROR) gl_fail("cannot allocate the shadow maps");
}

MfcRenderer::Gl::~Gl() {
  make_current();
  for (auto& m : meshes) {
    glDeleteBuffers(1, &m.vbo);
    glDeleteVertexArrays(1, &m.vao);
  }
  glDeleteTextures(3, color_tex.data());
  glDeleteTextures(3, surface_tex.data());
  glDeleteRenderbuffers(1, &depth_rb);
  glDeleteFramebuffers(1, &fbo);
  glDeleteFramebuffers(1, &surface_fbo);
  glDeleteVertexArrays(1, &empty_vao);
  glDeleteFramebuffers(1, &shadow_fbo);
  glDeleteTextures(1, &shadow_tex);
  for (GLuint prog : {scene_program, depth_program, shadow_program, surface_program, shade_programs[0],
                      shade_programs[1], lit_mask_program})
    glDeleteProgram(prog);
}

void MfcRenderer::Gl::make_target(GLuint& target, std::array<GLuint, 3>& tex, cv::Size size) const {
  glGenFramebuffers(1, &target);
  glBindFramebuffer(GL_FRAMEBUFFER, target);
  glGenTextures(3, tex.data());
  for (int i = 0; i < 3; ++i) {
    glBindTexture(GL_TEXTURE_2D, tex[static_cast<size_t>(i)]);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, size.width, size.height, 0, GL_RGBA, GL_FLOAT, nullptr);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glFramebufferTexture2D(GL_FRAMEBUFFER, static_cast<GLenum>(GL_COLOR_ATTACHMENT0 + i), GL_TEXTURE_2D,
                           tex[static_cast<size_t>(i)], 0);
  }
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_STENCIL_ATTACHMENT, GL_RENDERBUFFER, depth_rb);
  if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    gl_fail("float render target incomplete (" + std::to_string(size.width) + "x" + std::to_string(size.height) + ")");
}

void MfcRenderer::Gl::ensure_targets(cv::Size size) {
  if (fbo_size == size) return;
  if (fbo) {
    glDeleteTextures(3, color_tex.data());
    glDeleteTextures(3, surface_tex.data());
    glDeleteRenderbuffers(1, &depth_rb);
    glDeleteFramebuffers(1, &fbo);
    glDeleteFramebuffers(1, &surface_fbo);
  }
  glGenRenderbuffers(1, &depth_rb);
  glBindRenderbuffer(GL_RENDERBUFFER, depth_rb);
  // The stencil marks the pixels a masked render lights (Lighting::lit).
  glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH32F_STENCIL8, size.width, size.height);
  make_target(fbo, color_tex, size);
  surface_fbo = 0;  // the surfaces follow at the first deferred render
  surface_tex = {};
  surfaces_drawn.region = cv::Rect();
  fbo_size = size;
}

void MfcRenderer::Gl::ensure_surfaces() {
  if (!surface_fbo) make_target(surface_fbo, surface_tex, fbo_size);
}

int MfcRenderer::Gl::upload_mesh(const std::vector<float>& data, const Mesh& mesh) {
  GpuMesh g;
  glGenVertexArrays(1, &g.vao);
  glBindVertexArray(g.vao);
  glGenBuffers(1, &g.vbo);
  glBindBuffer(GL_ARRAY_BUFFER, g.vbo);
  glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(data.size() * sizeof(float)), data.data(), GL_STATIC_DRAW);
  glEnableVertexAttribArray(0);
  glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 6 * sizeof(float), nullptr);
  glEnableVertexAttribArray(1);
  glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, 6 * sizeof(float), reinterpret_cast<void*>(3 * sizeof(float)));
  glBindVertexArray(0);
  g.vertex_count = static_cast<GLsizei>(data.size() / 6);
  g.lo = g.hi = mesh.vertices.front();
  for (const cv::Vec3f& v : mesh.vertices)
    for (int a = 0; a < 3; ++a) g.lo[a] = std::min(g.lo[a], v[a]), g.hi[a] = std::max(g.hi[a], v[a]);
  if (glGetError() != GL_NO_ERROR) gl_fail("cannot upload mesh '" + mesh.name + "'");
  meshes.push_back(g);
  return static_cast<int>(meshes.size() - 1);
}

}  // namespace mfcd::vision
