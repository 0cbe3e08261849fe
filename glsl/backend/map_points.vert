#version 330
// Per-vertex evaluation of the parameter block, captured by transform
// feedback (varying "fpw_mapped"; rasterization is discarded).
//   FPW_BATCH: a batch of point sets in one pass (fpiwarp/backends/gl/
//   batch_points.py): vertex i is point i % fpw_batch_points of set
//   i / fpw_batch_points, mapped by block (i / fpw_batch_points) *
//   fpw_batch_step of the storage buffer (fpw_batch, a plain global here).
#ifdef FPW_BATCH
#define FPW_BATCH_VARYING
#endif
#include "include/fpiwarp.glsl"

in vec2 fpw_point;
out vec2 fpw_mapped;
#ifdef FPW_BATCH
uniform int fpw_batch_points;
uniform int fpw_batch_step;
#endif

void main() {
#ifdef FPW_BATCH
    fpw_batch = ivec3(gl_VertexID / fpw_batch_points * fpw_batch_step, 0, 0);
#endif
    fpw_mapped = fpw_map(fpw_point);
    gl_Position = vec4(0.0, 0.0, 0.0, 1.0);
}
