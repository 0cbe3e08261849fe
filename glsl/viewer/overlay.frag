#version 330
// Overlays of fpiwarp.gl.Renderer: the interpolated vertex colour, blended
// over the warped image (non-premultiplied alpha).
in vec4 ov_vcolor;
layout(location = 0) out vec4 ov_frag;

void main() {
    ov_frag = ov_vcolor;
}
