#version 430
// Vertex stage shared by every pass that draws meshes.
layout(location = 0) in vec3 in_position;
layout(location = 1) in vec3 in_normal;
layout(location = 2) in vec2 in_uv;
layout(location = 3) in vec3 in_color;
#ifdef HAS_TANGENTS
layout(location = 4) in vec4 in_tangent;  // xyz along +u, w handedness
out vec4 v_tangent;
#endif
layout(location = 5) in vec2 in_sky;  // sky visibility: front, back (app/sky_light.py)

uniform mat4 u_view_projection;
#ifdef OBJECT_TABLE
// Merged meshes (render.gpu_scene.GpuGroup): each vertex names its mesh, whose row of the
// per-object table carries what a per-mesh draw sets as uniforms (TCR tint and level).
layout(location = 6) in int in_object;
layout(std430, binding = OBJECT_TABLE_BINDING) readonly buffer ObjectTable {
    vec4 objects[];  // rgb: TCR tint, a: TCR level minus the texture's resident base
};
flat out int v_object;
flat out vec4 v_object_row;
#endif

out vec3 v_world;
out vec3 v_normal;
out vec2 v_uv;
out vec3 v_color;
#ifdef AO_BAKED
layout(location = 7) in vec2 in_ao;  // baked occlusion, front and back (render/ao.py)
out vec2 v_ao;
#endif
out vec2 v_sky;

void main() {
    v_world = in_position;
    v_normal = in_normal;
    v_uv = in_uv;
    v_color = in_color;
#ifdef HAS_TANGENTS
    v_tangent = in_tangent;
#endif
#ifdef AO_BAKED
    v_ao = in_ao;
#endif
    v_sky = in_sky;
#ifdef OBJECT_TABLE
    v_object = in_object;
    v_object_row = objects[in_object];
#endif
    gl_Position = u_view_projection * vec4(in_position, 1.0);
}
