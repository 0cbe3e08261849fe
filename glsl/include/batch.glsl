// Batches (FPW_BATCH): one instanced draw warps a stack of images into a
// tall atlas of outputs. Instance k draws output rows [k * rows, (k + 1) *
// rows) of the framebuffer, samples layer k of the source texture array and
// evaluates its own parameter block, one of the N blocks stacked in a
// shader storage buffer (N blocks do not fit one uniform block). The
// accessor differs, not the math: `fpw_rows` names the instance's block,
// and every line of include/map.glsl reads it as the single-image path does.
// Before including, a stage defines
//   FPW_BATCH_VARYING  `flat out` (vertex stage) or `flat in` (fragment);
//   FPW_BATCH_BLOCK    the index of the instance's block.
// fpw_batch = (block, source layer, first framebuffer row of the instance).
#extension GL_ARB_shader_storage_buffer_object : require
struct FpwBlock {
    vec4 rows[FPW_MAX_ROWS];
};
layout(std430) buffer FpiwarpBatch {
    FpwBlock fpw_blocks[];
};
#define fpw_rows fpw_blocks[FPW_BATCH_BLOCK].rows
FPW_BATCH_VARYING ivec3 fpw_batch;
