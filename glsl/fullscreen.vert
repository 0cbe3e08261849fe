#version 330
// One triangle that covers the whole viewport, without vertex buffers
// (draw 3 vertices with an attribute-less vertex array).
void main() {
    vec2 p = vec2(gl_VertexID == 1 ? 3.0 : -1.0, gl_VertexID == 2 ? 3.0 : -1.0);
    gl_Position = vec4(p, 0.0, 1.0);
}
