#version 330
// The coarse pass of a per-pixel warp or preview of a map with a Newton
// core (fpiwarp/block/coarse.py, coarse_pass): drawn with fullscreen.vert
// into two RGBA32F targets of nx x ny texels, fragment (i, j) solves node
// (i, j), which lies at window pixel COARSE_STEP (i, j) of the draw it
// seeds; fpw_view is that draw's, moved to its viewport's corner (see
// fpiwarp/backends/gl/coarse.py). The stage walk is fpw_map's (map.glsl,
// FPW_COARSE_PASS): it stops at the block's first Newton stage. A batch
// (FPW_BATCH, instanced as warp.frag's) solves image k's nodes, block k's,
// into texel rows [k ny, (k + 1) ny) (fpw_batch_rows = ny).
#include "include/fpiwarp.glsl"
#include "include/per_draw.glsl"
FPW_DECLARE_PER_DRAW

layout(location = 0) out vec4 fpw_out_xa;
layout(location = 1) out vec4 fpw_out_b;

void main() {
    // the pixels that read node (i, j) lie within COARSE_STEP pixels of it in x and y
    fpw_node_reach = float(FPW_COARSE_STEP) * length(fpw_view.zw);
    fpw_map(fpw_view.xy + fpw_view.zw * (float(FPW_COARSE_STEP) * (FPW_FRAG_XY - 0.5)));
    fpw_out_xa = vec4(fpw_node_x, fpw_node_a);
    fpw_out_b = vec4(fpw_node_b, 0.0, 0.0);
}
