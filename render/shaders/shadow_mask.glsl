// The screen-space shadow mask in the lighting (render/shadow_mask.py). The mask pass leaves
// each eye, at every u_mask_step-th pixel of each axis, the shadow factor of up to 8
// shadowed lights (slots 0-3 in x, 4-7 in y, 8 bits each), the sample's view distance (z, float
// bits) and normal (w, 8 bits a component), in one RGBA32UI texel; the lighting reads the
// pixel's factors once, before its light loop (use_shadow_mask_of: the four samples around the
// pixel, bilinear weights times how close each sample's surface lies to this pixel's in depth
// and in orientation, so no shadow bleeds across an edge or into the other side of a crease),
// and the loop does no shadow-map taps for those lights. A light's slot is shadow_light[i].z (-1: none).
//   SHADOW_MASK 1: every shadowed light has a slot (no per-pixel lookups at all);
//   SHADOW_MASK 2: more than 8 are shadowed, the others look up their maps per pixel.
// Without SHADOW_MASK the loop calls shadow_factor as before.
#ifdef SHADOW_MASK
uniform usampler2D u_shadow_mask;
uniform vec2 u_mask_depth;  // view distance = y / (ndc_z + x), from the eye's projection
uniform int u_mask_step;  // a sample every this many pixels (a uniform: no variant per step)
vec4 g_shadow_mask0 = vec4(1.0);
vec4 g_shadow_mask1 = vec4(1.0);

float mask_distance(float depth) {
    float den = depth * 2.0 - 1.0 + u_mask_depth.x;
    return u_mask_depth.y / (abs(den) > 1e-9 ? den : -1e-9);
}

void use_shadow_mask_of(ivec2 p, float depth, vec3 N) {
    float dist = mask_distance(depth);
    ivec2 last = textureSize(u_shadow_mask, 0) - 1;
    vec2 c = (vec2(p) - float(u_mask_step / 2)) / float(max(u_mask_step, 1));
    ivec2 base = ivec2(floor(c));
    vec2 f = c - vec2(base);
    float tol = 0.02 * dist + 0.01;
    vec4 sum0 = vec4(0.0);
    vec4 sum1 = vec4(0.0);
    float weight = 0.0;
    for (int k = 0; k < 4; ++k) {
        ivec2 o = ivec2(k & 1, k >> 1);
        uvec4 m = texelFetch(u_shadow_mask, clamp(base + o, ivec2(0), last), 0);
        vec2 b = mix(1.0 - f, f, vec2(o));
        float w = 1.0 / (1.0 + abs(uintBitsToFloat(m.z) - dist) / tol);
        float n = max(dot(unpackSnorm4x8(m.w).xyz, N), 0.0);
        n *= n;
        n *= n;
        w *= w * n * n;
        w = b.x * b.y * w * w + 1e-7;
        sum0 += unpackUnorm4x8(m.x) * w;
#if SHADOW_MASK_SLOTS_USED > 4
        sum1 += unpackUnorm4x8(m.y) * w;
#endif
        weight += w;
    }
    g_shadow_mask0 = sum0 / weight;
#if SHADOW_MASK_SLOTS_USED > 4
    g_shadow_mask1 = sum1 / weight;
#endif
}

// Light i's shadow factor from the mask (a light without a slot has no map: 1), or, where
// more lights are shadowed than the mask holds, from its map.
float masked_shadow(int i, vec3 P, vec3 N, vec3 L, float dist) {
    int slot = shadow_light[i].z;
    float m = dot(g_shadow_mask0, vec4(equal(ivec4(slot), ivec4(0, 1, 2, 3))));
#if SHADOW_MASK_SLOTS_USED > 4
    m += dot(g_shadow_mask1, vec4(equal(ivec4(slot), ivec4(4, 5, 6, 7))));
#endif
#if SHADOW_MASK == 2
    if (slot < 0) return shadow_factor(i, P, N, L, dist);
#endif
    return slot < 0 ? 1.0 : m;
}
#else
void use_shadow_mask_of(ivec2 p, float depth, vec3 N) {}

float masked_shadow(int i, vec3 P, vec3 N, vec3 L, float dist) {
    return shadow_factor(i, P, N, L, dist);
}
#endif
