#version 330
// Overlays of fpiwarp.gl.Renderer (handles, outlines): flat-coloured
// triangles whose corners the host computes in normalized device
// coordinates (sizes in screen pixels, independent of the zoom).
in vec2 ov_position;
in vec4 ov_color;
out vec4 ov_vcolor;

void main() {
    gl_Position = vec4(ov_position, 0.0, 1.0);
    ov_vcolor = ov_color;
}
