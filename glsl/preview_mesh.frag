#version 330
// Real-time preview (fpiwarp.gl.Renderer), mesh path: mesh.vert moves a
// grid of the source by the FORWARD map (no inverse, no Newton steps:
// fast for thin-plate-spline maps) and this shades the interpolated
// source position with preview_shade.glsl.
#include "fpiwarp_map.glsl"
#include "preview_shade.glsl"

noperspective in vec2 fpw_src_pos;

void main() {
    fpw_frag = pv_shade(fpw_src_pos);
}
