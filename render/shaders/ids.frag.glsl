#version 430
// Object ids (mesh index + 1; 0 = nothing) for error masks; rendered only on request.
#include "alpha_mask.glsl"

#ifndef OBJECT_TABLE
uniform float u_id;
#endif

layout(location = 0) out vec4 out_id;

void main() {
    alpha_mask();
#ifdef OBJECT_TABLE
    out_id = vec4(float(v_object + 1), 0.0, 0.0, 1.0);
#else
    out_id = vec4(u_id, 0.0, 0.0, 1.0);
#endif
}
