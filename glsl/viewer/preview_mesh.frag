#version 330
// Real-time preview (fpiwarp.gl.Renderer), mesh path: mesh.vert moves a
// grid of the source by the FORWARD map (no inverse, no Newton steps:
// fast for thin-plate-spline maps) and this shades the interpolated
// source position with preview_shade.glsl. With FPW_ANTIALIAS, the
// footprint of a screen pixel (fpiwarp/_antialias.py) has the edges
// d src / d window x and y, exact for the piecewise linear mesh.
#include "include/fpiwarp.glsl"
#include "viewer/preview_shade.glsl"

noperspective in vec2 fpw_src_pos;

void main() {
#ifdef FPW_ANTIALIAS
    vec2 ex = dFdx(fpw_src_pos), ey = dFdy(fpw_src_pos);
    fpw_frag = pv_shade_value(fpw_src_pos, fpw_sample_footprint(fpw_src_pos, ex, ey));
#else
    fpw_frag = pv_shade(fpw_src_pos);
#endif
}
