// The sampler: software sampling of the source texture, mirroring
// fpiwarp/_sampling.py (sample / border_index / _taps). Reads the per-draw
// values declared from per_draw.glsl. Part of fpiwarp.glsl (FPW_WITH_SAMPLER).

// ---- software sampling (_sampling.py) -------------------------------------
// Integer images are integer textures read with texelFetch: weights and
// sums are computed here in float, never by the texture unit.
// FPW_GATHER_C(uv, c): channel c of the 2×2 texels around uv, as floats.
// A batch (FPW_BATCH) reads layer fpw_batch.y of a texture array; the
// texel and gather coordinates below are the single image's otherwise. A
// batch draw of one image (FPW_BATCH_SINGLE) reads a 2D texture as the
// single image does: llvmpipe samples an array about 13% slower, even at a
// constant layer (fpiwarp/backends/gl/batch.py).
#if defined(FPW_BATCH) && !defined(FPW_BATCH_SINGLE)
#define FPW_SAMPLER sampler2DArray
#define FPW_USAMPLER usampler2DArray
#define FPW_AT(ij) ivec3(ij, fpw_batch.y)
#define FPW_UV(uv) vec3(uv, float(fpw_batch.y))
#else
#define FPW_SAMPLER sampler2D
#define FPW_USAMPLER usampler2D
#define FPW_AT(ij) ij
#define FPW_UV(uv) uv
#endif
#if defined(FPW_INT_TEXTURE)
uniform FPW_USAMPLER fpw_src;
vec4 fpw_fetch(ivec2 ij) { return vec4(texelFetch(fpw_src, FPW_AT(ij), 0)); }
#define FPW_GATHER_C(uv, c) vec4(textureGather(fpw_src, FPW_UV(uv), c))
#elif defined(FPW_UNORM_TEXTURE)
// uint8 as a normalized texture: texel v reads as v / 255 (the common,
// fastest texture format of software rasterizers); * 255 gives v back to
// within 1e-5, far below the rounding step.
uniform FPW_SAMPLER fpw_src;
vec4 fpw_fetch(ivec2 ij) { return texelFetch(fpw_src, FPW_AT(ij), 0) * FPW_UNORM_TEXTURE; }
#define FPW_GATHER_C(uv, c) (textureGather(fpw_src, FPW_UV(uv), c) * FPW_UNORM_TEXTURE)
#else
uniform FPW_SAMPLER fpw_src;
vec4 fpw_fetch(ivec2 ij) { return texelFetch(fpw_src, FPW_AT(ij), 0); }
#define FPW_GATHER_C(uv, c) textureGather(fpw_src, FPW_UV(uv), c)
#endif

// FPW_TILED: the texture holds source pixels fpw_tile = [x0, x0 + w) ×
// [y0, y0 + h) only: taps elsewhere contribute nothing, so summing one pass
// per tile (additive blending) gives the whole sum. The primary pass
// (fpw_primary != 0) also adds cval where the reference uses it, exactly once.

vec4 fpw_cval_term() {
#ifdef FPW_TILED
    return fpw_primary != 0 ? fpw_cval : vec4(0.0);
#else
    return fpw_cval;
#endif
}

// i mod n in [0, n) for any sign of i (GLSL's % is undefined for negatives).
int fpw_posmod(int i, int n) {
    return i >= 0 ? i % n : (n - 1) - ((-i - 1) % n);
}

// FPW_MODE is a constant: the `if`s below fold away. (As a uniform it would
// serve every mode with one program, but ran 2-4x slower on llvmpipe.)

// border_index: remap one integer index along an axis of length n.
int fpw_border(int i, int n) {
    if (FPW_MODE == FPW_MODE_CONSTANT || FPW_MODE == FPW_MODE_EDGE) return clamp(i, 0, n - 1);
    if (FPW_MODE == FPW_MODE_WRAP) return fpw_posmod(i, n);
    if (n == 1) return 0;
    int period = 2 * (n - 1);
    int m = fpw_posmod(i, period);
    return m >= n ? period - m : m;
}

// The texel at border-treated indices (col, row); `inside` tells whether
// the tap's own indices were inside the image ('constant' mode: cval).
vec4 fpw_texel(int col, int row, bool inside) {
    if (FPW_MODE == FPW_MODE_CONSTANT && !inside) return fpw_cval_term();
    ivec2 ij = ivec2(col, row);
#ifdef FPW_TILED
    ij -= fpw_tile.xy;
    if (any(lessThan(ij, ivec2(0))) || any(greaterThanEqual(ij, fpw_tile.zw))) return vec4(0.0);
#endif
    return fpw_fetch(ij);
}

// _cubic_weights: Keys' cubic convolution, a = -0.5, offsets -1, 0, 1, 2.
vec4 fpw_cubic_weights(float t) {
    float t2 = t * t;
    float t3 = t2 * t;
    return vec4(-0.5 * t3 + t2 - 0.5 * t,
                1.5 * t3 - 2.5 * t2 + 1.0,
                -1.5 * t3 + 2.0 * t2 + 0.5 * t,
                0.5 * t3 - 0.5 * t2);
}

#ifdef FPW_HW_FILTER
// The explicit fast option: the texture unit filters a normalized texture
// (nearest or linear, border by the sampler object). GL quantizes the
// bilinear weights (often to 8 bits), so results differ slightly from the
// reference; non-finite positions still give cval.
// fpw_hw_sample reads at source position pos; with FPW_ANTIALIAS the
// texture has mipmaps and it reads by textureGrad with the footprint edges
// ex, ey (source pixels, converted to texture coordinates): the texture
// unit's trilinear (and anisotropic) minification, see antialias.glsl.
// fpw_sample is the plain option's read; with mipmaps it names a level of
// detail below 0 (textureLod: magnified by the spec's rule, level 0
// through the plain option's own filter, bit for bit; zero gradients would
// leave the level to log2(0)). A driver whose anisotropic filter breaks
// this gets none (GLWarper.checked_anisotropy: llvmpipe's blurs it).
vec4 fpw_hw_sample(vec2 pos, vec2 ex, vec2 ey) {
    if (!fpw_in_range(pos)) return fpw_cval;
    pos = clamp(pos, vec2(-FPW_COORD_LIMIT), vec2(FPW_COORD_LIMIT));
    vec2 size = vec2(fpw_src_size);
    vec2 uv = (pos + 0.5) / size;
#ifdef FPW_ANTIALIAS
    if (ex == vec2(0.0) && ey == vec2(0.0)) return fpw_hw_scale * textureLod(fpw_src, uv, -1.0);
    return fpw_hw_scale * textureGrad(fpw_src, uv, ex / size, ey / size);
#else
    return fpw_hw_scale * texture(fpw_src, uv);
#endif
}

vec4 fpw_sample(vec2 pos) { return fpw_hw_sample(pos, vec2(0.0), vec2(0.0)); }
#elif defined(FPW_GATHER)
// Order 1 by textureGather, for 'constant', 'edge' and 'wrap' on untiled
// sources: one call per channel returns that channel of the 2×2 taps, where
// the texelFetch path below makes one call per tap (three calls instead of
// four for RGB, one for gray; texture calls are the dearest operation on
// llvmpipe). The host sets the texture's wrap mode (CLAMP_TO_EDGE, REPEAT
// for 'wrap') so the texture unit places the taps as fpw_border does;
// weights, cval and the order of the sum are those of the path below.
vec4 fpw_sample(vec2 pos) {
    if (!fpw_in_range(pos)) return fpw_cval_term();
    vec2 base = floor(pos);
    vec2 t = pos - base;
    ivec2 size = fpw_src_size;
    ivec2 i = ivec2(base);
#if FPW_MODE == FPW_MODE_WRAP
    i = ivec2(fpw_posmod(i.x, size.x), fpw_posmod(i.y, size.y));
#else
    i = clamp(i, ivec2(-2), size);  // farther out: the same taps ('edge'), none inside ('constant')
#endif
    // The corner the four texels share: (i + 1) / size, within
    // (i + 1) * 2^-24 texel of it (< 2^-8 for any texture side up to 2^16):
    // far from the half texel that would pick other texels.
    vec2 uv = (vec2(i) + 1.0) / vec2(size);
    // Gathered components: x (i, j+1), y (i+1, j+1), z (i+1, j), w (i, j).
    // Channels the image lacks are 0 (alpha 1); no output reads them.
    mat4 g = mat4(vec4(0.0), vec4(0.0), vec4(0.0), vec4(1.0));  // g[channel]
    g[0] = FPW_GATHER_C(uv, 0);
#if FPW_CHANNELS >= 2
    g[1] = FPW_GATHER_C(uv, 1);
#endif
#if FPW_CHANNELS >= 3
    g[2] = FPW_GATHER_C(uv, 2);
#endif
#if FPW_CHANNELS >= 4
    g[3] = FPW_GATHER_C(uv, 3);
#endif
    mat4 taps = transpose(g);  // taps[k]: all channels of gathered component k
    vec4 t00 = taps[3], t10 = taps[2], t01 = taps[0], t11 = taps[1];  // t<column><row>
#if FPW_MODE == FPW_MODE_CONSTANT
    bvec2 in0 = bvec2(i.x >= 0 && i.x < size.x, i.y >= 0 && i.y < size.y);
    bvec2 in1 = bvec2(i.x + 1 >= 0 && i.x + 1 < size.x, i.y + 1 >= 0 && i.y + 1 < size.y);
    vec4 cv = fpw_cval_term();
    if (!(in0.x && in0.y)) t00 = cv;
    if (!(in1.x && in0.y)) t10 = cv;
    if (!(in0.x && in1.y)) t01 = cv;
    if (!(in1.x && in1.y)) t11 = cv;
#endif
    float wx0 = 1.0 - t.x, wx1 = t.x, wy0 = 1.0 - t.y, wy1 = t.y;
    vec4 out_ = vec4(0.0);
    out_ += (wy0 * wx0) * t00;
    out_ += (wy0 * wx1) * t10;
    out_ += (wy1 * wx0) * t01;
    out_ += (wy1 * wx1) * t11;
    return out_;
}
#else
// Taps per axis: _taps gives 1, 2 or 4 integer positions with weights.
#if FPW_ORDER == 0
#define FPW_TAPS 1
#elif FPW_ORDER == 1
#define FPW_TAPS 2
#else
#define FPW_TAPS 4
#endif

// sample: the value at real position pos = (x, y), before rounding. Like
// the reference, the column indices are border-treated once, each row in
// the loop, and the sum runs row by row, column by column.
vec4 fpw_sample(vec2 pos) {
    if (!fpw_in_range(pos)) return fpw_cval_term();
    pos = clamp(pos, vec2(-FPW_COORD_LIMIT), vec2(FPW_COORD_LIMIT));
    float wx[FPW_TAPS];
    float wy[FPW_TAPS];
#if FPW_ORDER == 0
    ivec2 first = ivec2(floor(pos + 0.5));
    wx[0] = 1.0;
    wy[0] = 1.0;
#else
    vec2 base = floor(pos);
    vec2 t = pos - base;
#if FPW_ORDER == 1
    ivec2 first = ivec2(base);
    wx[0] = 1.0 - t.x; wx[1] = t.x;
    wy[0] = 1.0 - t.y; wy[1] = t.y;
#else
    ivec2 first = ivec2(base) - 1;
    vec4 cx = fpw_cubic_weights(t.x);
    vec4 cy = fpw_cubic_weights(t.y);
    for (int k = 0; k < 4; ++k) {
        wx[k] = cx[k];
        wy[k] = cy[k];
    }
#endif
#endif
    int cols[FPW_TAPS];
    bool cols_in[FPW_TAPS];
    for (int k = 0; k < FPW_TAPS; ++k) {
        int i = first.x + k;
        cols[k] = fpw_border(i, fpw_src_size.x);
        cols_in[k] = i >= 0 && i < fpw_src_size.x;
    }
    vec4 out_ = vec4(0.0);
    for (int r = 0; r < FPW_TAPS; ++r) {
        int j = first.y + r;
        int row = fpw_border(j, fpw_src_size.y);
        bool row_in = j >= 0 && j < fpw_src_size.y;
        for (int k = 0; k < FPW_TAPS; ++k) {
            out_ += (wy[r] * wx[k]) * fpw_texel(cols[k], row, row_in && cols_in[k]);
        }
    }
    return out_;
}
#endif  // FPW_HW_FILTER / FPW_GATHER
