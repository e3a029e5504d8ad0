#version 430
// The sky behind everything: the baked equirectangular sky (row 0 the zenith, the middle
// column north) and the sun's disc, in cd/m2.
#include "common.glsl"

in vec2 v_ndc;
uniform mat4 u_inv_view_projection;
uniform vec3 u_eye;
uniform sampler2D u_sky;
uniform vec3 u_sky_north;
uniform vec3 u_sky_east;
uniform vec3 u_sun_to;
uniform vec3 u_sun_disc;     // the disc's radiance (cd/m2, dimmed); zero at night
uniform float u_sun_cos;     // cosine of the disc's angular radius
uniform float u_sky_scale;   // the dimmer

layout(location = 0) out vec4 out_color;

void main() {
    vec4 far = u_inv_view_projection * vec4(v_ndc, 1.0, 1.0);
    vec3 d = safe_normalize(far.xyz / far.w - u_eye, vec3(0.0, 0.0, -1.0));
    float phi = atan(dot(d, u_sky_east), dot(d, u_sky_north));
    vec2 uv = vec2(phi / (2.0 * PI) + 0.5, acos(clamp(d.y, -1.0, 1.0)) / PI);
    vec3 c = textureLod(u_sky, uv, 0.0).rgb * u_sky_scale;
    if (dot(d, u_sun_to) >= u_sun_cos) c += u_sun_disc;
    out_color = vec4(storable(c), 1.0);
}
