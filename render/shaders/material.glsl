// Surface inputs shared by the G-buffer and the forward path.
// Texture sampling is compiled per mode (a uniform branch made llvmpipe run every path):
//   default    hardware trilinear mipmapping (TCR off: full quality)
//   TCR_PAPER  exactly pyramid level j (the paper's method)
//   TCR_CLAMP  mipmapping with the finest level limited to j
#include "common.glsl"

in vec3 v_world;
in vec3 v_normal;
in vec2 v_uv;
in vec3 v_color;
in vec2 v_sky;

uniform vec4 u_base_color;  // linear RGBA
uniform float u_roughness;
uniform float u_metallic;
#ifdef HAS_TEXTURE
uniform sampler2D u_albedo;  // sRGB pyramid, repeat-wrapped; level 0 = the finest resident level
uniform float u_level;       // TCR level j minus the resident base level (may be negative)
#endif
#ifdef TCR_TINT
uniform vec3 u_tint;  // the level's legend colour, or (1, 1, 1) for level 0
#endif

vec3 surface_albedo() {
    vec3 c = u_base_color.rgb * v_color;
#ifdef HAS_TEXTURE
#if defined(TCR_PAPER)
    c *= textureLod(u_albedo, v_uv, max(u_level, 0.0)).rgb;
#elif defined(TCR_CLAMP)
    c *= textureLod(u_albedo, v_uv, max(textureQueryLod(u_albedo, v_uv).y, u_level)).rgb;
#else
    c *= texture(u_albedo, v_uv).rgb;
#endif
#endif
#ifdef TCR_TINT
    // Paint the level's colour with the surface's luminance kept, so the texture stays
    // readable and a brightly lit surface does not wash the colour out to white. Level 0
    // (tint white) keeps its own colours.
    if (u_tint != vec3(1.0)) {
        c = u_tint * (0.25 + 0.75 * dot(c, vec3(0.2126, 0.7152, 0.0722)));
    }
#endif
    return clamp(c, vec3(0.0), vec3(1.0));
}

vec3 surface_normal() {
    vec3 n = safe_normalize(v_normal, vec3(0.0, 1.0, 0.0));
    return gl_FrontFacing ? n : -n;  // interiors are seen from both sides
}

float surface_sky() {
    return gl_FrontFacing ? v_sky.x : v_sky.y;  // the share of the sky the side seen sees
}
