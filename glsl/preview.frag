#version 330
// Real-time preview (fpiwarp.gl.Renderer), per pixel: the backward warp of
// warp.frag (the block of the INVERSE map evaluated at each output pixel),
// shaded for display by preview_shade.glsl.
#include "fpiwarp_map.glsl"
#include "preview_shade.glsl"

void main() {
    vec2 xy = fpw_view.xy + fpw_view.zw * (gl_FragCoord.xy - 0.5);
    fpw_frag = pv_shade(fpw_map(xy));
}
