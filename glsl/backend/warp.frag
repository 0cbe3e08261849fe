#version 330
// Per-pixel backward warp: each fragment evaluates the parameter block (the
// INVERSE of the user's map) at its own output position and samples the
// source there.
#include "include/fpiwarp.glsl"

// Output position of a fragment, in fpiwarp's pixel convention (centers at
// integers, x = column, y = row): view.xy + view.zw * (gl_FragCoord.xy - 0.5).
// gl_FragCoord is at the pixel center (i + 0.5, j + 0.5): the -0.5 puts the
// center on an integer. With view = (x0, y0, 1, 1) window row j is output
// row y0 + j, so glReadPixels (bottom row first) returns rows top-down in
// image order; a viewer drawing to a y-up screen passes a negative view.w.
// (fpw_view is a per-draw value, declared by include/fpiwarp.glsl from the
// list in per_draw.glsl.)

// A batch (FPW_BATCH) draws image k at framebuffer rows from fpw_batch.z on
// (see batch.glsl): its fragments count rows from there (FPW_FRAG_XY,
// include/block.glsl).

void main() {
#if defined(FPW_PACK_PIXELS)
    // Window column j holds output columns FPW_PACK_PIXELS * j + k.
    vec2 xy = fpw_view.xy + fpw_view.zw * vec2(FPW_PACK_PIXELS * (FPW_FRAG_XY.x - 0.5), FPW_FRAG_XY.y - 0.5);
    fpw_emit_packed(xy, fpw_view.z);
#elif defined(FPW_FILL)
    fpw_emit(fpw_cval);
#else
    vec2 xy = fpw_view.xy + fpw_view.zw * (FPW_FRAG_XY - 0.5);
#ifdef FPW_ANTIALIAS
    fpw_emit(fpw_sample_antialiased(xy));
#else
    fpw_emit(fpw_sample(FPW_PIXEL_MAP(xy)));  // FPW_COARSE: seeded (map.glsl)
#endif
#endif
}
