#pragma once
// GLSL sources of the MFC renderer's three programs (OpenGL 3.3 core).
//
// scene:  per pixel, the 8 flash images, the ambient image, camera-frame depth (mm) and the
//         part index, into three RGBA32F attachments (flash 0-3, flash 4-7, ambient/depth/id).
// depth:  the scene program's vertex stage with only the third attachment written (ambient 0):
//         the same rasterisation, hence the same depth and index, without the 8 lights.
// shadow: depth only, from one LED.

namespace mfcd::vision::shaders {

inline constexpr const char* kSceneVs = R"(#version 330 core
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

inline constexpr const char* kSceneFs = R"(#version 330 core
in vec3 v_pos;
in vec3 v_normal;
in vec3 v_model;
layout(location = 0) out vec4 o_flash0123;
layout(location = 1) out vec4 o_flash4567;
layout(location = 2) out vec4 o_ambient_depth_id;
uniform float u_part_id;
uniform vec3 u_led[8];
uniform mat4 u_shadow_from_camera[8];   // camera frame -> shadow map [0,1]^3
uniform sampler2DArrayShadow u_shadow;
uniform float u_flash_dn;               // white matte facing an LED at the working distance
uniform float u_working_distance;
uniform float u_ambient_dn;
uniform float u_room_dn;
uniform vec3 u_room_dir;
uniform float u_albedo, u_diffuse, u_specular, u_shininess;
uniform int u_paint;                    // 0 none, 1 stripes, 2 checker
uniform float u_paint_period, u_paint_albedo;
uniform float u_normal_offset;

float albedo() {
  if (u_paint == 0) return u_albedo;
  vec3 q = floor(v_model / u_paint_period);
  float odd = (u_paint == 1) ? mod(q.x, 2.0) : mod(q.x + q.y + q.z, 2.0);
  return odd > 0.5 ? u_paint_albedo : u_albedo;
}

void main() {
  vec3 n = normalize(v_normal);
  vec3 view = normalize(-v_pos);
  if (dot(n, view) < 0.0) n = -n;   // two-sided: open meshes and planes
  float a = albedo();
  float room = u_ambient_dn + u_room_dn * max(dot(n, normalize(u_room_dir)), 0.0);
  o_ambient_depth_id = vec4(a * room, v_pos.z, u_part_id, 0.0);
  float flash[8];
  for (int i = 0; i < 8; ++i) {
    vec3 to_led = u_led[i] - v_pos;
    float d = length(to_led);
    vec3 l = to_led / d;
    float ndl = dot(n, l);
    float value = 0.0;
    if (ndl > 0.0) {
      vec3 h = normalize(l + view);
      float spec = u_specular * pow(max(dot(n, h), 0.0), u_shininess);
      float falloff = (u_working_distance * u_working_distance) / (d * d);
      // Offset along the normal (scaled with distance) against self-shadowing acne.
      vec4 s = u_shadow_from_camera[i] * vec4(v_pos + n * u_normal_offset * d, 1.0);
      vec3 sc = s.xyz / s.w;
      float lit = 1.0;
      if (all(greaterThanEqual(sc.xy, vec2(0.0))) && all(lessThanEqual(sc.xy, vec2(1.0))))
        lit = texture(u_shadow, vec4(sc.xy, float(i), sc.z));
      value = u_flash_dn * falloff * lit * (u_diffuse * a * ndl + spec * ndl);
    }
    flash[i] = value;
  }
  o_flash0123 = vec4(flash[0], flash[1], flash[2], flash[3]);
  o_flash4567 = vec4(flash[4], flash[5], flash[6], flash[7]);
}
)";

inline constexpr const char* kShadowVs = R"(#version 330 core
layout(location = 0) in vec3 a_pos;
uniform mat4 u_clip_from_model;
void main() { gl_Position = u_clip_from_model * vec4(a_pos, 1.0); }
)";

inline constexpr const char* kShadowFs = R"(#version 330 core
void main() {}
)";

inline constexpr const char* kDepthFs = R"(#version 330 core
in vec3 v_pos;
layout(location = 2) out vec4 o_ambient_depth_id;
uniform float u_part_id;
void main() { o_ambient_depth_id = vec4(0.0, v_pos.z, u_part_id, 0.0); }
)";

}  // namespace mfcd::vision::shaders
