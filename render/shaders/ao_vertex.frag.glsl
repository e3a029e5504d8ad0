#version 430
// The baked occlusion of the visible surface (AO_BAKED: interpolated from the vertices), and,
// for the forward method, the world normal the screen-space occlusion needs (PREPASS).
#include "common.glsl"

in vec3 v_world;
in vec3 v_normal;
#ifdef AO_BAKED
in vec2 v_ao;  // over the normal, behind it
#endif
uniform float u_ao_strength;

layout(location = 0) out vec4 out_ao;
#ifdef PREPASS
layout(location = 1) out vec4 out_normal;
#endif

void main() {
    float a = 1.0;
#ifdef AO_BAKED
    a = gl_FrontFacing ? v_ao.x : v_ao.y;  // the side surface_normal() shades
    a = (isnan(a) || isinf(a)) ? 1.0 : clamp(a, 0.0, 1.0);
#endif
    out_ao = vec4(mix(1.0, a, u_ao_strength), 0.0, 0.0, 1.0);
#ifdef PREPASS
    vec3 n = safe_normalize(v_normal, vec3(0.0, 1.0, 0.0));
    out_normal = vec4(gl_FrontFacing ? n : -n, 0.0);
#endif
}
