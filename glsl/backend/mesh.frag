#version 330
// Texture mapping of the deformed mesh: sample the source at the
// interpolated source position with the software sampler.
#include "include/fpiwarp.glsl"

noperspective in vec2 fpw_src_pos;

void main() {
    fpw_emit(fpw_sample(fpw_src_pos));
}
