#version 330
// Per-vertex evaluation of the parameter block, captured by transform
// feedback (varying "fpw_mapped"; rasterization is discarded).
#include "fpiwarp_map.glsl"

in vec2 fpw_point;
out vec2 fpw_mapped;

void main() {
    fpw_mapped = fpw_map(fpw_point);
    gl_Position = vec4(0.0, 0.0, 0.0, 1.0);
}
