// fpw_pack: pixels of 3 channels in the bytes of one RGB32UI texel, in
// memory order on a little-endian host: 4 pixels of uint8, 2 of uint16
// (1 of float32 is its bits). Shared by warp.frag (FPW_PACK_PIXELS) and
// pack_rgb.frag; the host reads such texels back as a plain copy.
// Each value is masked to its width: one out-of-range value (never expected:
// outputs are clamped first) cannot spill into its neighbours.
uvec3 fpw_pack(uvec3 a, uvec3 b, uvec3 c, uvec3 d) {
    a &= 0xffu; b &= 0xffu; c &= 0xffu; d &= 0xffu;
    return uvec3(a.r | (a.g << 8) | (a.b << 16) | (b.r << 24),
                 b.g | (b.b << 8) | (c.r << 16) | (c.g << 24),
                 c.b | (d.r << 8) | (d.g << 16) | (d.b << 24));
}
uvec3 fpw_pack(uvec3 a, uvec3 b) {
    a &= 0xffffu; b &= 0xffffu;
    return uvec3(a.r | (a.g << 16), a.b | (b.r << 16), b.g | (b.b << 16));
}
