#version 430
// Photon gather at a list of points (tests, benchmarks): E for point i into pm_out[i].xyz.
// Groups of 64 consecutive points play the role of the G-buffer entry's 8x8 tiles (SHARED).
// Core defines as in photon_gather.glsl.
layout(local_size_x = 64) in;
#include "photon_gather.glsl"

layout(std430, binding = 3) readonly buffer QueryPoints { vec4 pm_points[]; };   // xyz
layout(std430, binding = 4) readonly buffer QueryNormals { vec4 pm_normals[]; }; // xyz, unit
layout(std430, binding = 5) writeonly buffer QueryOut { vec4 pm_out[]; };
uniform uint u_points;

void main() {
    uint i = gl_GlobalInvocationID.x;
    bool has_query = i < u_points;  // the tail of the last group still joins SHARED's barriers
    vec3 P = has_query ? pm_points[i].xyz : vec3(0.0);
    vec3 N = has_query ? pm_normals[i].xyz : vec3(0.0, 1.0, 0.0);
    vec3 E = gather_query(P, N, has_query);
    if (has_query) {
        pm_out[i] = vec4(E, 0.0);
#ifdef COUNT
        pm_count(0, 1u);
#endif
    }
}
