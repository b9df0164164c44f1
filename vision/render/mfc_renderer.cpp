#include "vision/render/mfc_renderer.hpp"

#include "vision/common/rotation.hpp"
#include "vision/render/gl_matrices.hpp"
#include "vision/render/render_gl.hpp"
#include "vision/render/sensor_capture.hpp"
#include "vision/render/shadow_footprint.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <random>
#include <stdexcept>
#include <string>

namespace mfcd::vision {

namespace {

using namespace gl_matrices;

constexpr int kFlashes = 8;
constexpr GLenum kAllAttachments[3] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1, GL_COLOR_ATTACHMENT2};

}  // namespace

MfcRenderer::MfcRenderer(const CameraConfig& config, const RenderOptions& options)
    : config_(config), camera_(config.camera), options_(options) {
  validate_camera_config(config_);
  if (config_.flashes.positions_mm.size() != kFlashes) gl_fail("the MFC renderer simulates exactly 8 LEDs");
  std::copy_n(config_.flashes.positions_mm.begin(), kFlashes, leds_.begin());
  const auto gl_lock = lock_gl();
  gl_ = std::make_unique<Gl>(options_.shadow_map_size);
}

MfcRenderer::~MfcRenderer() {
  const auto gl_lock = lock_gl();
  gl_.reset();
}

std::string MfcRenderer::gl_renderer() const {
  const auto gl_lock = lock_gl();
  gl_->make_current();
  const auto* s = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  return s ? s : "";
}

int MfcRenderer::add_mesh(const Mesh& mesh, double crease_deg) {
  MeshLoadOptions any_size;
  any_size.min_size_mm = 0;
  any_size.max_size_mm = 1e9;
  validate_mesh(mesh, any_size, mesh.name.empty() ? "mesh" : mesh.name);
  // Per-corner normals: the area-weighted mean of the normals of the faces around the
  // vertex that are within the crease angle of this face. Sharp CAD edges stay sharp,
  // tessellated curved surfaces shade smoothly.
  const size_t nt = mesh.triangles.size();
  std::vector<cv::Vec3f> face_normal(nt);  // length = 2 * area
  std::vector<std::vector<uint32_t>> faces_of_vertex(mesh.vertices.size());
  for (size_t f = 0; f < nt; ++f) {
    const auto& t = mesh.triangles[f];
    face_normal[f] = (mesh.vertices[t[1]] - mesh.vertices[t[0]]).cross(mesh.vertices[t[2]] - mesh.vertices[t[0]]);
    for (uint32_t v : t) faces_of_vertex[v].push_back(static_cast<uint32_t>(f));
  }
  const double cos_crease = std::cos(crease_deg * CV_PI / 180.0);
  std::vector<float> data;
  data.reserve(nt * 3 * 6);
  for (size_t f = 0; f < nt; ++f) {
    const cv::Vec3f nf = face_normal[f];
    const double lf = cv::norm(nf);
    for (uint32_t v : mesh.triangles[f]) {
      cv::Vec3f sum(0, 0, 0);
      for (uint32_t g : faces_of_vertex[v]) {
        const double lg = cv::norm(face_normal[g]);
        if (lf > 0 && lg > 0 && nf.dot(face_normal[g]) >= cos_crease * lf * lg) sum += face_normal[g];
      }
      const double ls = cv::norm(sum);
      const cv::Vec3f n = ls > 0 ? sum / ls : cv::Vec3f(0, 0, 1);
      const cv::Vec3f& p = mesh.vertices[v];
      data.insert(data.end(), {p[0], p[1], p[2], n[0], n[1], n[2]});
    }
  }
  const auto gl_lock = lock_gl();
  gl_->make_current();
  return gl_->upload_mesh(data, mesh);
}

void MfcRenderer::set_camera(const PinholeCamera& camera) {
  if (camera.image_size.width <= 0 || camera.image_size.height <= 0) gl_fail("camera image size must be positive");
  camera_ = camera;
}

std::pair<double, double> MfcRenderer::depth_range(std::span<const ScenePart> parts) const {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const auto& p : parts) {
    const auto& gm = gl_->meshes[static_cast<size_t>(p.mesh_id)];
    for (int k = 0; k < 8; ++k) {
      const cv::Vec3d c((k & 1) ? gm.hi[0] : gm.lo[0], (k & 2) ? gm.hi[1] : gm.lo[1], (k & 4) ? gm.hi[2] : gm.lo[2]);
      const double z = (p.R * c + p.t_mm)[2];
      lo = std::min(lo, z), hi = std::max(hi, z);
    }
  }
  return {std::max(lo, camera_near_mm()), std::min(hi, camera_far_mm())};
}

void MfcRenderer::draw_shadow_maps(std::span<const ScenePart> parts, const cv::Rect& region,
                                   std::span<cv::Matx44d, 8> unit_from_camera) {
  Gl& g = *gl_;
  // One perspective shadow map per LED, looking along +z from the LED. Its field of view
  // covers the camera's frustum from the near plane on, whatever the LED's offset.
  const double wd = config_.working_distance_mm;
  const double n = wd * options_.shadow_near_fraction, f = wd * options_.shadow_far_fraction;
  // The frustum comes from the configured full-frame camera, not a cropped one, so that
  // a window render sees exactly the same shadows as the full frame.
  const PinholeCamera& full = config_.camera;
  const double W = full.image_size.width, H = full.image_size.height;
  const double tan_x = std::max(full.cx() + 0.5, W - 0.5 - full.cx()) / full.fx();
  const double tan_y = std::max(full.cy() + 0.5, H - 0.5 - full.cy()) / full.fy();
  const int S = options_.shadow_map_size;
  glUseProgram(g.shadow_program);
  glBindFramebuffer(GL_FRAMEBUFFER, g.shadow_fbo);
  glDrawBuffer(GL_NONE);
  glReadBuffer(GL_NONE);
  glViewport(0, 0, S, S);
  glEnable(GL_DEPTH_CLAMP);
  glEnable(GL_POLYGON_OFFSET_FILL);
  glPolygonOffset(1.5f, 4.0f);
  glEnable(GL_SCISSOR_TEST);
  const GLint u_clip = glGetUniformLocation(g.shadow_program, "u_clip_from_model");
  // Only the texels this render can read are filled (shadow_footprint.hpp): every visible
  // surface lies within the parts' depth range.
  const auto [z_near, z_far] = depth_range(parts);
  // (A whole render copies no camera: it allocates nothing.)
  std::optional<PinholeCamera> cropped;
  if (region != cv::Rect(cv::Point(), camera_.image_size)) cropped = camera_.cropped(region);
  const PinholeCamera& drawn = cropped ? *cropped : camera_;
  for (int i = 0; i < kFlashes; ++i) {
    const cv::Vec3d L = leds_[static_cast<size_t>(i)];
    const double reach = std::hypot(L[0], L[1]) / n;
    const double fs = (S / 2.0) / (std::max(tan_x, tan_y) + reach);
    const cv::Matx33d Ks(fs, 0, S / 2.0 - 0.5, 0, fs, S / 2.0 - 0.5, 0, 0, 1);
    const cv::Matx44d led_from_camera(1, 0, 0, -L[0], 0, 1, 0, -L[1], 0, 0, 1, -L[2], 0, 0, 0, 1);
    const cv::Matx44d clip = clip_from_camera(Ks, {S, S}, n, f) * led_from_camera;
    const cv::Matx44d to_unit(0.5, 0, 0, 0.5, 0, 0.5, 0, 0.5, 0, 0, 0.5, 0.5, 0, 0, 0, 1);
    unit_from_camera[static_cast<size_t>(i)] = to_unit * clip;
    const ShadowFootprintQuery footprint{.unit_from_camera = unit_from_camera[static_cast<size_t>(i)],
                                         .map_size = S,
                                         .z_near_mm = z_near,
                                         .z_far_mm = z_far,
                                         .led_mm = L,
                                         .offset_per_mm = normal_offset()};
    const cv::Rect fill = options_.fill_whole_shadow_maps ? cv::Rect(0, 0, S, S) : shadow_footprint(footprint, drawn);
    glFramebufferTextureLayer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, g.shadow_tex, 0, i);
    glScissor(fill.x, fill.y, fill.width, fill.height);
    glClear(GL_DEPTH_BUFFER_BIT);
    if (fill.empty()) continue;
    for (const auto& p : parts) {
      if (!p.casts_shadows) continue;
      const Mat4 m = to_gl(clip * model_matrix(p.R, p.t_mm));
      glUniformMatrix4fv(u_clip, 1, GL_FALSE, m.data());
      const auto& gm = g.meshes[static_cast<size_t>(p.mesh_id)];
      glBindVertexArray(gm.vao);
      glDrawArrays(GL_TRIANGLES, 0, gm.vertex_count);
    }
  }
  glDisable(GL_SCISSOR_TEST);
  glDisable(GL_POLYGON_OFFSET_FILL);
  glDisable(GL_DEPTH_CLAMP);
}

void MfcRenderer::set_lights(unsigned prog, std::span<const cv::Matx44d, 8> unit_from_camera) {
  auto loc = [prog](const char* name) { return glGetUniformLocation(prog, name); };
  for (int i = 0; i < kFlashes; ++i) {
    const cv::Vec3d L = leds_[static_cast<size_t>(i)];
    char name[64];
    std::snprintf(name, sizeof name, "u_led[%d]", i);
    glUniform3f(loc(name), static_cast<float>(L[0]), static_cast<float>(L[1]), static_cast<float>(L[2]));
    const Mat4 s = to_gl(unit_from_camera[static_cast<size_t>(i)]);
    std::snprintf(name, sizeof name, "u_shadow_from_camera[%d]", i);
    glUniformMatrix4fv(loc(name), 1, GL_FALSE, s.data());
  }
  glActiveTexture(GL_TEXTURE0);
  glBindTexture(GL_TEXTURE_2D_ARRAY, gl_->shadow_tex);
  glUniform1i(loc("u_shadow"), 0);
  const Illumination& li = options_.light;
  glUniform1f(loc("u_flash_dn"), li.flash_dn);
  glUniform1f(loc("u_working_distance"), static_cast<float>(config_.working_distance_mm));
  glUniform1f(loc("u_ambient_dn"), li.ambient_dn);
  glUniform1f(loc("u_room_dn"), li.room_dn);
  const cv::Vec3d rd = cv::normalize(li.room_direction);
  glUniform3f(loc("u_room_dir"), static_cast<float>(rd[0]), static_cast<float>(rd[1]), static_cast<float>(rd[2]));
  glUniform1f(loc("u_normal_offset"), static_cast<float>(normal_offset()));
}

namespace {

bool same_material(const Material& a, const Material& b) {
  return a.albedo == b.albedo && a.diffuse == b.diffuse && a.specular == b.specular && a.shininess == b.shininess &&
         a.paint == b.paint && a.paint_period_mm == b.paint_period_mm && a.paint_albedo == b.paint_albedo;
}

bool same_part(const ScenePart& a, const ScenePart& b) {
  return a.mesh_id == b.mesh_id && a.R == b.R && a.t_mm == b.t_mm && a.casts_shadows == b.casts_shadows &&
         same_material(a.material, b.material);
}

}  // namespace

bool MfcRenderer::surfaces_hold(std::span<const ScenePart> parts, const cv::Rect& region) const {
  const auto& d = gl_->surfaces_drawn;
  return gl_->surface_fbo && !d.region.empty() && (region & d.region) == region && d.K == camera_.K &&
         std::equal(parts.begin(), parts.end(), d.parts.begin(), d.parts.end(), same_part);
}

void MfcRenderer::draw_scene(std::span<const ScenePart> parts, Shading shading, const cv::Rect& region,
                             const cv::Mat1b* lit) {
  Gl& g = *gl_;
  g.ensure_targets(camera_.image_size);
  for (const auto& p : parts)
    if (p.mesh_id < 0 || p.mesh_id >= static_cast<int>(g.meshes.size()))
      gl_fail("scene part refers to unknown mesh id " + std::to_string(p.mesh_id));
  if (parts.size() > 255) gl_fail("at most 255 parts per scene");

  std::array<cv::Matx44d, kFlashes> unit_from_camera;
  glDisable(GL_CULL_FACE);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  if (shading != Shading::none) draw_shadow_maps(parts, region, unit_from_camera);
  if (shading == Shading::deferred) g.ensure_surfaces();
  // The surfaces a deferred render needs may be drawn already, when only the lighting changed.
  const bool surfaces_held = shading == Shading::deferred && surfaces_hold(parts, region);

  glBindFramebuffer(GL_FRAMEBUFFER, shading == Shading::deferred ? g.surface_fbo : g.fbo);
  // Without shading only the ambient/depth/index attachment is drawn (and cleared).
  const GLenum depth_only[3] = {GL_NONE, GL_NONE, GL_COLOR_ATTACHMENT2};
  glDrawBuffers(3, shading == Shading::none ? depth_only : kAllAttachments);
  const cv::Size size = camera_.image_size;
  glViewport(0, 0, size.width, size.height);
  // Window coordinates count rows from the bottom, and clip_from_camera puts image row 0 there:
  // the scissor box is the region as it stands. Nothing outside it is cleared, drawn or read.
  glEnable(GL_SCISSOR_TEST);
  glScissor(region.x, region.y, region.width, region.height);
  glClearColor(0, 0, 0, 0);
  if (!surfaces_held) glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  switch (shading) {
    case Shading::none:
      draw_parts(parts, g.depth_program, nullptr);
      break;
    case Shading::forward:
      draw_parts(parts, g.scene_program, &unit_from_camera);
      break;
    case Shading::deferred:
      if (!surfaces_held) {
        draw_parts(parts, g.surface_program, nullptr);
        g.surfaces_drawn.parts.assign(parts.begin(), parts.end());
        g.surfaces_drawn.K = camera_.K;
        g.surfaces_drawn.region = region;
      }
      shade_surfaces(unit_from_camera, lit, std::all_of(parts.begin(), parts.end(), [](const ScenePart& p) {
                       return p.material.specular == 0;
                     }));
      break;
  }
  glDisable(GL_SCISSOR_TEST);
  if (glGetError() != GL_NO_ERROR) gl_fail("OpenGL error while drawing the scene");
}

void MfcRenderer::draw_parts(std::span<const ScenePart> parts, unsigned prog,
                             const std::array<cv::Matx44d, 8>* unit_from_camera) {
  Gl& g = *gl_;
  glUseProgram(prog);
  auto loc = [prog](const char* name) { return glGetUniformLocation(prog, name); };
  const Mat4 clip = to_gl(clip_from_camera(camera_.K, camera_.image_size, camera_near_mm(), camera_far_mm()));
  glUniformMatrix4fv(loc("u_clip_from_camera"), 1, GL_FALSE, clip.data());
  if (unit_from_camera) set_lights(prog, *unit_from_camera);
  // Uniforms a program does not have are at location -1, where setting them does nothing.
  for (size_t k = 0; k < parts.size(); ++k) {
    const ScenePart& p = parts[k];
    const Mat4 m = to_gl(model_matrix(p.R, p.t_mm));
    glUniformMatrix4fv(loc("u_camera_from_model"), 1, GL_FALSE, m.data());
    glUniform1f(loc("u_part_id"), static_cast<float>(k + 1));
    const Material& mat = p.material;
    glUniform1f(loc("u_albedo"), mat.albedo);
    glUniform1f(loc("u_diffuse"), mat.diffuse);
    glUniform1f(loc("u_specular"), mat.specular);
    glUniform1f(loc("u_shininess"), mat.shininess);
    glUniform1i(loc("u_paint"), static_cast<int>(mat.paint));
    glUniform1f(loc("u_paint_period"), mat.paint_period_mm);
    glUniform1f(loc("u_paint_albedo"), mat.paint_albedo);
    const auto& gm = g.meshes[static_cast<size_t>(p.mesh_id)];
    glBindVertexArray(gm.vao);
    glDrawArrays(GL_TRIANGLES, 0, gm.vertex_count);
  }
  glBindVertexArray(0);
}

void MfcRenderer::shade_surfaces(const std::array<cv::Matx44d, 8>& unit_from_camera, const cv::Mat1b* lit, bool matte) {
  Gl& g = *gl_;
  glBindFramebuffer(GL_FRAMEBUFFER, g.fbo);
  glDrawBuffers(3, kAllAttachments);
  glDisable(GL_DEPTH_TEST);
  if (lit) mark_lit_pixels(*lit);
  const GLuint prog = g.shade_programs[matte ? 1 : 0];
  glUseProgram(prog);
  set_lights(prog, unit_from_camera);  // texture unit 0: the shadow maps
  const char* names[3] = {"u_pos_id", "u_normal_albedo", "u_material"};
  for (int i = 0; i < 3; ++i) {
    glActiveTexture(static_cast<GLenum>(GL_TEXTURE1 + i));
    glBindTexture(GL_TEXTURE_2D, g.surface_tex[static_cast<size_t>(i)]);
    glUniform1i(glGetUniformLocation(prog, names[i]), 1 + i);
  }
  glBindVertexArray(g.empty_vao);
  glDrawArrays(GL_TRIANGLES, 0, 3);
  glBindVertexArray(0);
  // Every render starts from the same texture state: another would make llvmpipe compile
  // another variant of the programs (and allocate) on the next render.
  for (int i = 0; i < 3; ++i) {
    glActiveTexture(static_cast<GLenum>(GL_TEXTURE1 + i));
    glBindTexture(GL_TEXTURE_2D, 0);
  }
  glActiveTexture(GL_TEXTURE0);
  glDisable(GL_STENCIL_TEST);
  glEnable(GL_DEPTH_TEST);
}

int MfcRenderer::lit_tile_px(cv::Size image) {
  int tile = 8;
  while (((image.width + tile - 1) / tile) * ((image.height + tile - 1) / tile) > kMaxLitTiles) tile *= 2;
  return tile;
}

void MfcRenderer::mark_lit_pixels(const cv::Mat1b& lit) {
  Gl& g = *gl_;
  // What is left unlit keeps the cleared value: nothing there (the scissor box is the region's).
  glClearStencil(0);
  glClear(GL_COLOR_BUFFER_BIT | GL_STENCIL_BUFFER_BIT);
  // The lit tiles as bits of a uniform array: no texture upload per render, so no resource
  // mapping (egl_context.hpp, lock_gl, says why llvmpipe's mappings are to be kept few).
  const int tile = lit_tile_px(lit.size());
  const int shift = std::countr_zero(static_cast<unsigned>(tile));
  const int per_row = (lit.cols + tile - 1) / tile;
  g.lit_tiles.assign(kMaxLitTiles / 32, 0u);
  for (int y = 0; y < lit.rows; ++y) {
    const uint8_t* row = lit.ptr<uint8_t>(y);
    const int base = (y >> shift) * per_row;
    for (int x = 0; x < lit.cols; ++x)
      if (row[x]) {
        const int t = base + (x >> shift);
        g.lit_tiles[static_cast<size_t>(t >> 5)] |= 1u << (t & 31);
      }
  }
  const GLuint prog = g.lit_mask_program;
  glUseProgram(prog);
  glUniform4uiv(glGetUniformLocation(prog, "u_tiles"), kMaxLitTiles / 128, g.lit_tiles.data());
  glUniform1i(glGetUniformLocation(prog, "u_tile_shift"), shift);
  glUniform1i(glGetUniformLocation(prog, "u_tiles_per_row"), per_row);
  glEnable(GL_STENCIL_TEST);
  glStencilFunc(GL_ALWAYS, 1, 0xff);
  glStencilOp(GL_KEEP, GL_KEEP, GL_REPLACE);
  glColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
  glBindVertexArray(g.empty_vao);
  glDrawArrays(GL_TRIANGLES, 0, 3);
  glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
  glStencilFunc(GL_EQUAL, 1, 0xff);
  glStencilOp(GL_KEEP, GL_KEEP, GL_KEEP);
}

void MfcRenderer::render_depth(std::span<const ScenePart> parts, cv::Mat1f& depth_mm, cv::Mat1b& part_index) {
  const auto gl_lock = lock_gl();
  gl_->make_current();
  draw_scene(parts, Shading::none, cv::Rect(cv::Point(), camera_.image_size));
  const cv::Size size = camera_.image_size;
  const size_t n = static_cast<size_t>(size.area());
  readback_.resize(n * 4);
  glReadBuffer(GL_COLOR_ATTACHMENT2);
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  glReadPixels(0, 0, size.width, size.height, GL_RGBA, GL_FLOAT, readback_.data());
  depth_mm.create(size);
  part_index.create(size);
  for (int y = 0; y < size.height; ++y) {
    const float* src = readback_.data() + static_cast<size_t>(y) * size.width * 4;
    float* d = depth_mm.ptr<float>(y);
    uint8_t* id = part_index.ptr<uint8_t>(y);
    for (int x = 0; x < size.width; ++x) {
      d[x] = src[4 * x + 1];
      id[x] = static_cast<uint8_t>(src[4 * x + 2]);
    }
  }
}

void MfcRenderer::render(std::span<const ScenePart> parts, MfcRender& out, uint64_t noise_seed, cv::Rect region,
                         const Lighting& lighting) {
  const cv::Rect whole(cv::Point(), camera_.image_size);
  if (region.empty()) region = whole;
  if ((region & whole) != region)
    throw std::invalid_argument("render region " + std::to_string(region.width) + "x" + std::to_string(region.height) +
                                " at (" + std::to_string(region.x) + ", " + std::to_string(region.y) +
                                ") reaches outside the image");
  if (lighting.lit && lighting.lit->size() != camera_.image_size)
    throw std::invalid_argument(
        "render: the lit mask is " + std::to_string(lighting.lit->cols) + "x" + std::to_string(lighting.lit->rows) +
        ", the image " + std::to_string(camera_.image_size.width) + "x" + std::to_string(camera_.image_size.height));
  if (lighting.lit && !options_.deferred_shading)
    throw std::invalid_argument("render: a lit mask needs deferred shading");
  const cv::Matx33d turn = rotation_about_z(lighting.ring_turn_rad);
  for (size_t i = 0; i < leds_.size(); ++i)
    leds_[i] = lighting.ring_turn_rad == 0 ? config_.flashes.positions_mm[i] : turn * config_.flashes.positions_mm[i];
  {
    const auto gl_lock = lock_gl();
    gl_->make_current();
    draw_scene(parts, options_.deferred_shading ? Shading::deferred : Shading::forward, region, lighting.lit);
    read_back(region, out);
  }
  capture_frames(options_.noise, noise_seed, out, noise_);
}

void MfcRenderer::read_back(const cv::Rect& region, MfcRender& out) {
  const cv::Size size = camera_.image_size;
  const size_t n = static_cast<size_t>(region.area());
  readback_.resize(n * 12);
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  for (int a = 0; a < 3; ++a) {
    glReadBuffer(static_cast<GLenum>(GL_COLOR_ATTACHMENT0 + a));
    glReadPixels(region.x, region.y, region.width, region.height, GL_RGBA, GL_FLOAT,
                 readback_.data() + n * 4 * static_cast<size_t>(a));
  }
  out.flash_linear.resize(kFlashes);
  for (auto& f : out.flash_linear) f.create(size);
  out.ambient_linear.create(size);
  out.depth_mm.create(size);
  out.part_index.create(size);
  if (region.size() != size) {  // what is not drawn reads as empty
    for (auto& f : out.flash_linear) f.setTo(0);
    out.ambient_linear.setTo(0);
    out.depth_mm.setTo(0);
    out.part_index.setTo(0);
  }

  const float* p0 = readback_.data();
  const float* p1 = p0 + n * 4;
  const float* p2 = p1 + n * 4;
  for (int y = 0; y < region.height; ++y) {
    const size_t row = static_cast<size_t>(y) * static_cast<size_t>(region.width);
    const int iy = region.y + y;
    float* amb = out.ambient_linear.ptr<float>(iy) + region.x;
    float* depth = out.depth_mm.ptr<float>(iy) + region.x;
    uint8_t* id = out.part_index.ptr<uint8_t>(iy) + region.x;
    std::array<float*, kFlashes> fl;
    for (size_t i = 0; i < kFlashes; ++i) fl[i] = out.flash_linear[i].ptr<float>(iy) + region.x;
    for (int x = 0; x < region.width; ++x) {
      const size_t k = (row + static_cast<size_t>(x)) * 4;
      const float ambient = p2[k];
      amb[x] = ambient;
      depth[x] = p2[k + 1];
      id[x] = static_cast<uint8_t>(p2[k + 2]);
      // Every flash image also sees the ambient light, as a real capture does.
      for (size_t i = 0; i < 4; ++i) {
        fl[i][x] = p0[k + i] + ambient;
        fl[i + 4][x] = p1[k + i] + ambient;
      }
    }
  }
}

}  // namespace mfcd::vision
