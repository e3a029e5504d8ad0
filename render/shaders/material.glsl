// Surface inputs shared by the G-buffer and the forward path.
#include "common.glsl"

in vec3 v_world;
in vec3 v_normal;
in vec2 v_uv;
in vec3 v_color;

uniform vec4 u_base_color;  // linear RGBA
uniform float u_roughness;
uniform float u_metallic;
#ifdef HAS_TEXTURE
uniform sampler2D u_albedo;  // sRGB texture, mipmapped, repeat-wrapped
#endif

vec3 surface_albedo() {
    vec3 c = u_base_color.rgb * v_color;
#ifdef HAS_TEXTURE
    c *= texture(u_albedo, v_uv).rgb;
#endif
    return clamp(c, vec3(0.0), vec3(1.0));
}

vec3 surface_normal() {
    vec3 n = safe_normalize(v_normal, vec3(0.0, 1.0, 0.0));
    return gl_FrontFacing ? n : -n;  // interiors are seen from both sides
}
