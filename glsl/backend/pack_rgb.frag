#version 330
// Packs a 3-channel picture into 12-byte texels (RGB32UI) for the readback,
// after passes that do not pack their own pixels (warp.frag does for
// FPI-like maps at order <= 1: FPW_PACK_PIXELS; not for the mesh path,
// cubic sampling, thin-plate splines, regions or generic programs).
// Reading 3 channels out of an RGBA target makes the driver convert every
// pixel on the CPU (a 4K uint8 frame: ~107 ms on NVIDIA's driver, ~15 ms on
// llvmpipe); an RGB32UI target reads back as a plain copy (~3 ms), and this
// pass costs about what it saves on llvmpipe. Draw it with fullscreen.vert
// into a target FPW_PACK_PIXELS times narrower than fpw_unpacked:
// FPW_PACK_PIXELS pixels of 3 channels per texel, 4 (uint8), 2 (uint16) or
// 1 (float32, FPW_PACK_FLOAT: the bits as they are). Bytes go in memory
// order on a little-endian host (the host checks).
#include "include/pack.glsl"
#ifdef FPW_PACK_FLOAT
uniform sampler2D fpw_unpacked;
uvec4 fpw_bits(int x, int y) { return floatBitsToUint(texelFetch(fpw_unpacked, ivec2(x, y), 0)); }
#else
uniform usampler2D fpw_unpacked;
uvec4 fpw_bits(int x, int y) { return texelFetch(fpw_unpacked, ivec2(x, y), 0); }
#endif

layout(location = 0) out uvec3 fpw_packed;

void main() {
    int y = int(gl_FragCoord.y);
    int x = FPW_PACK_PIXELS * int(gl_FragCoord.x);
    // Texels beyond the picture's width give padding that the host drops.
#if FPW_PACK_PIXELS == 4
    fpw_packed = fpw_pack(fpw_bits(x, y).rgb, fpw_bits(x + 1, y).rgb, fpw_bits(x + 2, y).rgb, fpw_bits(x + 3, y).rgb);
#elif FPW_PACK_PIXELS == 2
    fpw_packed = fpw_pack(fpw_bits(x, y).rgb, fpw_bits(x + 1, y).rgb);
#else
    fpw_packed = fpw_bits(x, y).rgb;
#endif
}
