// The fragment output: fpw_emit in the output kind the host chose, and
// the integer rounding of to_dtype. Part of fpiwarp.glsl (FPW_WITH_SAMPLER).

// to_dtype for integer outputs: floor(v + 0.5) clipped to [0, top].
uvec4 fpw_round(vec4 v, float top) {
    return uvec4(clamp(floor(v + 0.5), vec4(0.0), vec4(top)));
}

// ---- fragment output ---------------------------------------------------------
// fpw_emit(v) writes a sampled value in the output kind the host chose:
//   FPW_ACCUMULATE: float sums for tiled sources (additive blending); the
//                   second output marks covered pixels (the mesh path);
//   FPW_PACK_PIXELS: 3-channel pictures, FPW_PACK_PIXELS pixels per
//                   RGB32UI texel (fpw_emit_packed, fpw_pack; see
//                   pack_rgb.frag), rounded like FPW_OUT_INT when integer;
//   FPW_OUT_INT:    rounded and clipped to [0, fpw_top] (integer images);
//   FPW_OUT_ROUNDED: the same, times fpw_out_scale (uint8 into a unorm texture);
//   otherwise:      float, times fpw_out_scale (1 for float images; e.g.
//                   1/255 to show a uint8 image in a normalized target).
#if defined(FPW_ACCUMULATE)
layout(location = 0) out vec4 fpw_frag;
layout(location = 1) out vec4 fpw_cover;
void fpw_emit(vec4 v) {
    fpw_frag = v;
    fpw_cover = vec4(fpw_primary != 0 ? 1.0 : 0.0);
}
#elif defined(FPW_PACK_PIXELS)
#include "include/pack.glsl"
layout(location = 0) out uvec3 fpw_packed;
// One output pixel's three channels as they are stored: rounded integers,
// or a float's bits.
uvec3 fpw_stored(vec2 xy) {
    vec4 v = fpw_sample(fpw_map(xy));
#if FPW_PACK_PIXELS == 1  // 4-byte channels: float32, stored as they are
    return floatBitsToUint(v.rgb);
#else
    return fpw_round(v, fpw_top).rgb;
#endif
}
// The FPW_PACK_PIXELS output pixels from xy on, `dx` apart along x.
void fpw_emit_packed(vec2 xy, float dx) {
#if FPW_PACK_PIXELS == 4
    fpw_packed = fpw_pack(fpw_stored(xy), fpw_stored(xy + vec2(dx, 0.0)),
                          fpw_stored(xy + vec2(2.0 * dx, 0.0)), fpw_stored(xy + vec2(3.0 * dx, 0.0)));
#elif FPW_PACK_PIXELS == 2
    fpw_packed = fpw_pack(fpw_stored(xy), fpw_stored(xy + vec2(dx, 0.0)));
#else
    fpw_packed = fpw_stored(xy);
#endif
}
#elif defined(FPW_OUT_INT)
layout(location = 0) out uvec4 fpw_frag;
void fpw_emit(vec4 v) { fpw_frag = fpw_round(v, fpw_top); }
#elif defined(FPW_OUT_ROUNDED)
// an integer image into a normalized target (a uint8 texture): k / 255
// stores k exactly, so the rounding is the reference's
layout(location = 0) out vec4 fpw_frag;
void fpw_emit(vec4 v) { fpw_frag = vec4(fpw_round(v, fpw_top)) * fpw_out_scale; }
#else
layout(location = 0) out vec4 fpw_frag;
void fpw_emit(vec4 v) { fpw_frag = v * fpw_out_scale; }
#endif
