#version 330
// Real-time preview (fpiwarp.gl.Renderer), per pixel: the backward warp of
// warp.frag (the block of the INVERSE map evaluated at each output pixel),
// shaded for display by preview_shade.glsl.
//
// With FPW_ANTIALIAS (Renderer(antialias=True)) each screen pixel is the
// average over its footprint in the source (fpiwarp/_antialias.py): the
// edges are the inverse map's Jacobian columns at the pixel's output
// position times the view's scale (fpw_view.zw: output pixels per screen
// pixel), so a zoomed-out view is filtered by the map's shrinking and the
// view's together, and a zoomed-in view of a map that does not shrink is
// the plain draw, bit for bit.
#include "include/fpiwarp.glsl"
#include "viewer/preview_shade.glsl"

void main() {
    vec2 xy = fpw_view.xy + fpw_view.zw * (gl_FragCoord.xy - 0.5);
    vec2 src = FPW_PIXEL_MAP(xy);  // FPW_COARSE: seeded (map.glsl)
#ifdef FPW_ANTIALIAS
    vec2 dz, dzb;
    fpw_map_wirtinger(xy, dz, dzb);
    vec4 c = fpw_sample_footprint(src, fpw_edge_x(dz, dzb) * fpw_view.z, fpw_edge_y(dz, dzb) * fpw_view.w);
    fpw_frag = pv_shade_value(src, c);
#else
    fpw_frag = pv_shade(src);
#endif
}
