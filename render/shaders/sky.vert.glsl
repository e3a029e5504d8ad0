#version 430
// One triangle covering the viewport at the far plane: drawn with depth test "<=", it covers
// only the pixels no geometry wrote (the G-buffer's depth cleared to 1).
out vec2 v_ndc;

void main() {
    vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2) * 2.0 - 1.0;
    v_ndc = p;
    gl_Position = vec4(p, 1.0, 1.0);
}
