#version 330
// One triangle that covers the whole viewport, without vertex buffers
// (draw 3 vertices with an attribute-less vertex array).
//
// It also hands the fragment stage the per-draw values it reads for every
// pixel, as flat varyings (constant over the one triangle): Mesa's llvmpipe
// loads a uniform again for every pixel, a flat varying once per triangle,
// which makes a 4K warp about twice as fast there; GPUs do not care.
//   FPW_HOT_STAGES: rows FPW_ROW_PRE .. FPW_ROW_PRE + FPW_HOT_ROWS - 1 of the
//     first FPW_HOT_STAGES stages of the block (fpw_row in include/block.glsl);
//   FPW_FLAT_PER_DRAW: the per-draw values of the fragment program (the
//     list in per_draw.glsl), declared here as uniforms under their names
//     and copied into the flat members of the block FpwPerDraw.
//   FPW_BATCH: instance k covers framebuffer rows [k * fpw_batch_rows,
//     (k + 1) * fpw_batch_rows) of fpw_batch_count images (draw 6 vertices
//     per instance) and reads block k * fpw_batch_step (see batch.glsl).
#ifdef FPW_BATCH
#define FPW_BATCH_VARYING flat out
#define FPW_BATCH_BLOCK (gl_InstanceID * fpw_batch_step)
#include "include/batch.glsl"
uniform int fpw_batch_rows;
uniform int fpw_batch_count;
uniform int fpw_batch_step;
#endif
#ifdef FPW_HOT_STAGES
#ifndef FPW_BATCH
layout(std140) uniform FpiwarpParams {
    vec4 fpw_rows[FPW_MAX_ROWS];
};
#endif
flat out vec4 fpw_hot[FPW_HOT_ROWS * FPW_HOT_STAGES];
#endif
#include "include/per_draw.glsl"
FPW_FORWARD_PER_DRAW_DECLS

void main() {
#ifdef FPW_BATCH
    // two triangles over the instance's rows (pixel centers are half a
    // pixel from the edges: no rounding of the corners moves a pixel)
    int k = gl_InstanceID;
    fpw_batch = ivec3(FPW_BATCH_BLOCK, k, k * fpw_batch_rows);
    int v = gl_VertexID;
    float y = (v == 2 || v == 3 || v == 5) ? float(k + 1) : float(k);
    vec2 p = vec2((v == 1 || v == 4 || v == 5) ? 1.0 : -1.0, 2.0 * y / float(fpw_batch_count) - 1.0);
#else
    vec2 p = vec2(gl_VertexID == 1 ? 3.0 : -1.0, gl_VertexID == 2 ? 3.0 : -1.0);
#endif
    gl_Position = vec4(p, 0.0, 1.0);
#ifdef FPW_HOT_STAGES
    for (int k = 0; k < FPW_HOT_STAGES; ++k) {
        for (int j = 0; j < FPW_HOT_ROWS; ++j) {
            fpw_hot[FPW_HOT_ROWS * k + j] = fpw_rows[1 + k * FPW_STAGE_ROWS + FPW_ROW_PRE + j];
        }
    }
#endif
    FPW_FORWARD_PER_DRAW
}
