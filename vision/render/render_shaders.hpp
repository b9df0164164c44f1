#pragma once
// GLSL sources of the MFC renderer's programs (OpenGL 3.3 core). Each stage's source is a list
// of the pieces below, kVersion first.
//
// deferred (RenderOptions::deferred_shading): `surface` draws the parts and keeps each pixel's
//         nearest surface (position, normal, albedo, material) in three RGBA32F attachments;
//         `shade` then lights every pixel once from them. The lit cost is per pixel, however many
//         triangles (and thin slivers of tessellated curves) cover it.
// scene:  forward, the default: every drawn fragment lit, the nearest kept.
// Both write the 8 flash images, the ambient image, camera-frame depth (mm) and the part index
//         into three RGBA32F attachments (flash 0-3, flash 4-7, ambient/depth/id).
// depth:  the scene program's vertex stage with only the third attachment written (ambient 0):
//         the same rasterisation, hence the same depth and index, without the 8 lights.
// shadow: depth only, from one LED.

namespace mfcd::vision::shaders {

inline constexpr const char* kSceneVs = R"(
layout(location = 0) in vec3 a_pos;
layout(location = 1) in vec3 a_normal;
uniform mat4 u_camera_from_model;
uniform mat4 u_clip_from_camera;
out vec3 v_pos;      // camera frame, mm
out vec3 v_normal;   // camera frame
out vec3 v_model;    // part frame, mm (for painted patterns)
void main() {
  vec4 p = u_camera_from_model * vec4(a_pos, 1.0);
  v_pos = p.xyz;
  v_normal = mat3(u_camera_from_model) * a_normal;
  v_model = a_pos;
  gl_Position = u_clip_from_camera * p;
}
)";

// The lighting of one surface point, shared by the forward and the deferred scene programs
// (each program's source is kVersion, kLighting, then its own): the ambient image's value and
// the 8 flash images' before the ambient light is added. `n` is the unit normal turned towards
// the camera, `pos` the point in the camera frame (mm), `a` its albedo.
inline constexpr const char* kVersion = "#version 330 core\n";
inline constexpr const char* kMatte = "#define MFC_MATTE 1\n";

inline constexpr const char* kLighting = R"(
uniform vec3 u_led[8];
uniform mat4 u_shadow_from_camera[8];   // camera frame -> shadow map [0,1]^3
uniform sampler2DArrayShadow u_shadow;
uniform float u_flash_dn;               // white matte facing an LED at the working distance
uniform float u_working_distance;
uniform float u_ambient_dn;
uniform float u_room_dn;
uniform vec3 u_room_dir;
uniform float u_normal_offset;

float room_light(vec3 n, float a) {
  return a * (u_ambient_dn + u_room_dn * max(dot(n, normalize(u_room_dir)), 0.0));
}

void flash_light(vec3 pos, vec3 n, float a, vec3 material, out vec4 flash0123, out vec4 flash4567) {
  vec3 view = normalize(-pos);
  float flash[8];
  for (int i = 0; i < 8; ++i) {
    vec3 to_led = u_led[i] - pos;
    float d = length(to_led);
    vec3 l = to_led / d;
    float ndl = dot(n, l);
    float value = 0.0;
    if (ndl > 0.0) {
#ifdef MFC_MATTE
      float spec = 0.0;  // every part drawn has specular 0: the term below is 0 exactly
#else
      vec3 h = normalize(l + view);
      float spec = material.y * pow(max(dot(n, h), 0.0), material.z);
#endif
      float falloff = (u_working_distance * u_working_distance) / (d * d);
      // Offset along the normal (scaled with distance) against self-shadowing acne.
      vec4 s = u_shadow_from_camera[i] * vec4(pos + n * u_normal_offset * d, 1.0);
      vec3 sc = s.xyz / s.w;
      float lit = 1.0;
      if (all(greaterThanEqual(sc.xy, vec2(0.0))) && all(lessThanEqual(sc.xy, vec2(1.0))))
        lit = texture(u_shadow, vec4(sc.xy, float(i), sc.z));
      value = u_flash_dn * falloff * lit * (material.x * a * ndl + spec * ndl);
    }
    flash[i] = value;
  }
  flash0123 = vec4(flash[0], flash[1], flash[2], flash[3]);
  flash4567 = vec4(flash[4], flash[5], flash[6], flash[7]);
}
)";

// A drawn fragment's surface: unit normal towards the camera, albedo (painted or not) and the
// part's material (diffuse, specular, shininess).
inline constexpr const char* kSurface = R"(
in vec3 v_pos;
in vec3 v_normal;
in vec3 v_model;
uniform float u_part_id;
uniform float u_albedo, u_diffuse, u_specular, u_shininess;
uniform int u_paint;                    // 0 none, 1 stripes, 2 checker
uniform float u_paint_period, u_paint_albedo;

float albedo() {
  if (u_paint == 0) return u_albedo;
  vec3 q = floor(v_model / u_paint_period);
  float odd = (u_paint == 1) ? mod(q.x, 2.0) : mod(q.x + q.y + q.z, 2.0);
  return odd > 0.5 ? u_paint_albedo : u_albedo;
}

vec3 facing_normal() {
  vec3 n = normalize(v_normal);
  if (dot(n, normalize(-v_pos)) < 0.0) n = -n;   // two-sided: open meshes and planes
  return n;
}

vec3 material() { return vec3(u_diffuse, u_specular, u_shininess); }
)";

// Forward: every drawn fragment lit (the reference; kVersion + kLighting + kSurface + this).
inline constexpr const char* kSceneFs = R"(
layout(location = 0) out vec4 o_flash0123;
layout(location = 1) out vec4 o_flash4567;
layout(location = 2) out vec4 o_ambient_depth_id;
void main() {
  vec3 n = facing_normal();
  float a = albedo();
  o_ambient_depth_id = vec4(room_light(n, a), v_pos.z, u_part_id, 0.0);
  flash_light(v_pos, n, a, material(), o_flash0123, o_flash4567);
}
)";

// Deferred, first pass: the nearest surface of every pixel (kVersion + kSurface + this).
inline constexpr const char* kSurfaceFs = R"(
layout(location = 0) out vec4 o_pos_id;          // camera frame (mm), part index
layout(location = 1) out vec4 o_normal_albedo;
layout(location = 2) out vec4 o_material;
void main() {
  o_pos_id = vec4(v_pos, u_part_id);
  o_normal_albedo = vec4(facing_normal(), albedo());
  o_material = vec4(material(), 0.0);
}
)";

// Deferred, second pass: one triangle over the whole target, each pixel lit once from the
// first pass's surfaces (kVersion + this; the fragment stage kVersion, its variant's defines,
// kLighting, kShadeFs). MFC_MATTE leaves out the specular term, for scenes whose parts all have
// specular 0 (the same values).
inline constexpr const char* kFullScreenVs = R"(
void main() {
  vec2 corner = vec2(float((gl_VertexID & 1) << 2), float((gl_VertexID & 2) << 1));
  gl_Position = vec4(corner - 1.0, 0.0, 1.0);
}
)";

inline constexpr const char* kShadeFs = R"(
uniform sampler2D u_pos_id;
uniform sampler2D u_normal_albedo;
uniform sampler2D u_material;
layout(location = 0) out vec4 o_flash0123;
layout(location = 1) out vec4 o_flash4567;
layout(location = 2) out vec4 o_ambient_depth_id;
void main() {
  ivec2 px = ivec2(gl_FragCoord.xy);
  vec4 pos_id = texelFetch(u_pos_id, px, 0);
  if (pos_id.w == 0.0) {  // nothing drawn here
    o_flash0123 = vec4(0.0);
    o_flash4567 = vec4(0.0);
    o_ambient_depth_id = vec4(0.0);
    return;
  }
  vec4 na = texelFetch(u_normal_albedo, px, 0);
  o_ambient_depth_id = vec4(room_light(na.xyz, na.w), pos_id.z, pos_id.w, 0.0);
  flash_light(pos_id.xyz, na.xyz, na.w, texelFetch(u_material, px, 0).xyz, o_flash0123, o_flash4567);
}
)";

// The pixels to light (Lighting::lit) as the stencil the deferred second pass is tested
// against: drawn with the full-screen triangle, stencil replaced where not discarded. Testing
// the stencil happens before a fragment is shaded, which a discard in the lighting would not.
// The lit tiles come as bits of a uniform array (MfcRenderer::kMaxLitTiles of them).
inline constexpr const char* kLitMaskFs = R"(
uniform uvec4 u_tiles[256];  // bit t (word t / 32, bit t % 32): tile t, row-major, is lit
uniform int u_tile_shift;    // log2 of a tile's side in pixels
uniform int u_tiles_per_row;
void main() {
  ivec2 tile = ivec2(gl_FragCoord.xy) >> u_tile_shift;
  int t = tile.y * u_tiles_per_row + tile.x;
  uint word = u_tiles[t >> 7][(t >> 5) & 3];
  if (((word >> uint(t & 31)) & 1u) == 0u) discard;
}
)";

inline constexpr const char* kShadowVs = R"(
layout(location = 0) in vec3 a_pos;
uniform mat4 u_clip_from_model;
void main() { gl_Position = u_clip_from_model * vec4(a_pos, 1.0); }
)";

inline constexpr const char* kShadowFs = R"(
void main() {}
)";

inline constexpr const char* kDepthFs = R"(
in vec3 v_pos;
layout(location = 2) out vec4 o_ambient_depth_id;
uniform float u_part_id;
void main() { o_ambient_depth_id = vec4(0.0, v_pos.z, u_part_id, 0.0); }
)";

}  // namespace mfcd::vision::shaders
