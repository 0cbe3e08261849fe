// The parameter block (fpiwarp/block/layout.py): row 0 header, then the
// stages; fpw_rows[i] reads it, fpw_row(i) reads it through the flat
// varyings of a full-screen pass (FPW_HOT_STAGES). Part of fpiwarp.glsl.
//
// The parameter block: row 0 header, then the stages (fpiwarp/block/layout.py).
// std140 gives an array of vec4 a stride of 16 bytes: no padding traps.
#ifdef FPW_BATCH
// a batch: the instance's block of a storage buffer (see batch.glsl; a
// stage that sets fpw_batch itself defines FPW_BATCH_VARYING empty first)
#ifndef FPW_BATCH_VARYING
#define FPW_BATCH_VARYING flat in
#endif
#define FPW_BATCH_BLOCK fpw_batch.x
#include "include/batch.glsl"
#else
layout(std140) uniform FpiwarpParams {
    vec4 fpw_rows[FPW_MAX_ROWS];
};
#endif
// A fragment's window position counted from its image's first row: a
// batch (FPW_BATCH) draws image k at framebuffer rows from fpw_batch.z on
// (see batch.glsl), a single draw from row 0 (fragment stages only).
#ifdef FPW_BATCH
#define FPW_FRAG_XY (gl_FragCoord.xy - vec2(0.0, float(fpw_batch.z)))
#else
#define FPW_FRAG_XY gl_FragCoord.xy
#endif

// Row i of the block. In a full-screen pass (fullscreen.vert) specialized
// to a kind of map, the host defines FPW_HOT_STAGES: the rows read for
// every pixel of an FPI (FPW_ROW_PRE .. FPW_ROW_L3 of each of the first
// FPW_HOT_STAGES stages) then arrive as flat varyings written once by the
// vertex stage. Same values, bit for bit; but Mesa's llvmpipe loads a
// uniform again for every pixel (about 5 ms per vec4 per 4K frame on two
// cores), a flat varying once per triangle. With constant `i` (a
// specialized program) the choice below folds away.
#ifdef FPW_HOT_STAGES
flat in vec4 fpw_hot[FPW_HOT_ROWS * FPW_HOT_STAGES];
#endif
vec4 fpw_row(int i) {
#ifdef FPW_HOT_STAGES
    int k = (i - 1) / FPW_STAGE_ROWS;
    int r = (i - 1) - k * FPW_STAGE_ROWS;
    if (i >= 1 && k < FPW_HOT_STAGES && r >= FPW_ROW_PRE && r < FPW_ROW_PRE + FPW_HOT_ROWS) {
        return fpw_hot[FPW_HOT_ROWS * k + r - FPW_ROW_PRE];
    }
#endif
    return fpw_rows[i];
}
