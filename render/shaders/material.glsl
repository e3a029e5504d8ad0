// Surface inputs shared by every pass that draws meshes (G-buffer, forward, blend, emissive,
// ids and depth-only passes), per pixel from the material's maps (render/gpu_scene.py picks the
// variant with material_defines and binds with GpuScene.bind_material):
//   HAS_TEXTURE        base colour map (sRGB, alpha in A)
//   HAS_TANGENTS       a normal map in tangent space (the mesh has a tangent attribute)
//   HAS_MR_MAP         metallic-roughness map (G roughness, B metalness), times the factors
//   HAS_OCCLUSION_MAP  ambient occlusion map (R), mixed by the strength
//   HAS_EMISSIVE_MAP   emissive map (sRGB), times the emissive factor
//   UNLIT              KHR_materials_unlit: the glow (its colour) times the vertex colours
//   ALPHA_MASK         cut out below u_alpha_cutoff (alpha_mask.glsl)
//   OBJECT_TABLE       merged meshes: the TCR level and tint come per object from the vertex
//                      stage's table row (v_object_row), not from u_level / u_tint
// Base colour sampling is compiled per TCR mode (a uniform branch made llvmpipe run every path):
//   default    hardware trilinear mipmapping (TCR off: full quality)
//   TCR_PAPER  exactly pyramid level j (the paper's method)
//   TCR_CLAMP  mipmapping with the finest level limited to j
#include "common.glsl"

in vec3 v_world;
in vec3 v_normal;
in vec2 v_uv;
in vec3 v_color;
#ifdef HAS_TANGENTS
in vec4 v_tangent;
uniform sampler2D u_normal_map;  // linear, xyz * 2 - 1
uniform float u_normal_scale;
#endif
in vec2 v_sky;

uniform vec4 u_base_color;  // linear RGBA
uniform float u_roughness;
uniform float u_metallic;
uniform vec3 u_emissive;
uniform float u_alpha_cutoff;
#ifdef OBJECT_TABLE
flat in int v_object;      // the mesh's index
flat in vec4 v_object_row;  // its table row: TCR tint rgb, level minus the resident base
#endif
#ifdef HAS_TEXTURE
uniform sampler2D u_albedo;  // sRGB pyramid, repeat-wrapped; level 0 = the finest resident level
#ifdef OBJECT_TABLE
#define u_level (v_object_row.w)
#else
uniform float u_level;  // TCR level j minus the resident base level (may be negative)
#endif
#endif
#ifdef HAS_MR_MAP
uniform sampler2D u_mr_map;
#endif
#ifdef HAS_OCCLUSION_MAP
uniform sampler2D u_occlusion_map;
uniform float u_occlusion_strength;
#endif
#ifdef HAS_EMISSIVE_MAP
uniform sampler2D u_emissive_map;
#endif
#ifdef TCR_TINT
#ifdef OBJECT_TABLE
#define u_tint (v_object_row.xyz)
#else
uniform vec3 u_tint;  // the level's legend colour, or (1, 1, 1) for level 0
#endif
#endif

vec4 base_texel() {
#ifdef HAS_TEXTURE
#if defined(TCR_PAPER)
    return textureLod(u_albedo, v_uv, max(u_level, 0.0));
#elif defined(TCR_CLAMP)
    return textureLod(u_albedo, v_uv, max(textureQueryLod(u_albedo, v_uv).y, u_level));
#else
    return texture(u_albedo, v_uv);
#endif
#else
    return vec4(1.0);
#endif
}

// Coverage: the factor's alpha times the texture's (OPAQUE materials have both at 1).
float surface_alpha() {
    return u_base_color.a * base_texel().a;
}

vec3 surface_albedo() {
    vec3 c = u_base_color.rgb * v_color * base_texel().rgb;
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

// World normal of this pixel, facing the viewer's side: interiors are seen from both sides (the
// renderer culls nothing), so a back face shows its flipped normal, as glTF's doubleSided asks.
vec3 surface_normal() {
    vec3 n = safe_normalize(v_normal, vec3(0.0, 1.0, 0.0));
    float side = gl_FrontFacing ? 1.0 : -1.0;
    n *= side;
#ifdef HAS_TANGENTS
    // Tangent frame, re-orthogonalised per pixel (interpolation bends it); flipped with the face.
    vec3 m = texture(u_normal_map, v_uv).xyz * 2.0 - 1.0;  // outside the branch: derivatives
    m.xy *= u_normal_scale;
    vec3 t = v_tangent.xyz - n * dot(n, v_tangent.xyz);
    t = safe_normalize(t, vec3(0.0)) * side;
    if (dot(t, t) > 0.0) {
        vec3 b = cross(n, t) * (v_tangent.w < 0.0 ? -1.0 : 1.0) * side;
        n = safe_normalize(t * m.x + b * m.y + n * max(m.z, 0.0), n);
    }
#endif
    return n;
}

float surface_roughness() {
#ifdef HAS_MR_MAP
    return clamp(u_roughness * texture(u_mr_map, v_uv).g, 0.02, 1.0);
#else
    return u_roughness;
#endif
}

float surface_metallic() {
#ifdef HAS_MR_MAP
    return clamp(u_metallic * texture(u_mr_map, v_uv).b, 0.0, 1.0);
#else
    return u_metallic;
#endif
}

// Ambient occlusion of the material (1: none); only the ambient term takes it.
float surface_occlusion() {
#ifdef HAS_OCCLUSION_MAP
    return 1.0 + u_occlusion_strength * (texture(u_occlusion_map, v_uv).r - 1.0);
#else
    return 1.0;
#endif
}

vec3 surface_emissive() {
#ifdef HAS_EMISSIVE_MAP
    vec3 e = u_emissive * texture(u_emissive_map, v_uv).rgb;
#else
    vec3 e = u_emissive;
#endif
#ifdef UNLIT
    e *= v_color;  // KHR_materials_unlit: base colour x its map x the vertex colours
#endif
    return e;
}

float surface_sky() {
    return gl_FrontFacing ? v_sky.x : v_sky.y;  // the share of the sky the side seen sees
}
