// Alpha MASK cut-outs (leaves, fences) for every pass that draws meshes: the G-buffer, forward,
// blend, object ids and depth-only passes such as shadow maps. Compile the program with
// render.gpu_scene.alpha_mask_defines(mesh) (or material_defines), bind it with
// GpuScene.bind_material(prog, index), and call alpha_mask() first in main(). The vertex stage
// must be geometry.vert.glsl (or pass v_uv the same way). Without ALPHA_MASK it does nothing.
#include "material.glsl"

void alpha_mask() {
#ifdef ALPHA_MASK
    if (surface_alpha() < u_alpha_cutoff) discard;
#endif
}
