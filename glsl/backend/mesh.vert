#version 330
// The paper's own way: a triangulated mesh of the SOURCE, each vertex moved
// by the forward map (the parameter block of the user's map, no inverse
// needed), then rasterized with the source position as texture coordinate.
#include "include/fpiwarp.glsl"

in vec2 fpw_vertex;          // source position (x, y) of the vertex
uniform vec4 fpw_view;       // as in warp.frag: out = view.xy + view.zw * (window - 0.5)
uniform vec2 fpw_viewport;   // render target size in pixels

noperspective out vec2 fpw_src_pos;

void main() {
    vec2 w = fpw_map(fpw_vertex);
    bool ok = fpw_finite(w) && all(lessThan(abs(w), vec2(FPW_COORD_LIMIT)));
    vec2 window = ok ? (w - fpw_view.xy) / fpw_view.zw + 0.5 : vec2(0.0);
    gl_Position = vec4(window / fpw_viewport * 2.0 - 1.0, 0.0, 1.0);
    fpw_src_pos = fpw_vertex;
    // A vertex sent to the pole: a huge negative clip distance clips every
    // triangle that touches it down to nothing (the host enables
    // GL_CLIP_DISTANCE0). Cheaper than `discard`, which is slow on llvmpipe.
    gl_ClipDistance[0] = ok ? 1.0 : -1e30;
}
