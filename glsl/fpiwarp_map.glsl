// fpiwarp: evaluation of the parameter block and software image sampling.
//
// This include mirrors the numpy references line by line:
//   * fpw_map        <-> fpiwarp/params.py  evaluate / _evaluate_stage / _tps / _newton
//   * fpw_sample     <-> fpiwarp/_sampling.py  sample / border_index / _taps
// in float32. Complex numbers are vec2 (re, im). The host prepends the
// #defines below (see fpiwarp/backends/gl_backend.py) so that the block
// layout has exactly one definition, the one in params.py:
//   FPW_MAX_ROWS, FPW_STAGE_ROWS, FPW_ROW_* (row offsets in a stage),
//   FPW_CORE_AFFINE, FPW_CORE_TPS, FPW_COORD_LIMIT,
//   FPW_WITH_SAMPLER  (define to get the sampling functions), and then
//   FPW_ORDER (0, 1, 3), FPW_MODE (0 constant, 1 edge, 2 reflect, 3 wrap),
//   FPW_INT_TEXTURE (source is an unsigned integer texture),
//   FPW_TILED (the source texture is one tile of a larger image, see below),
//   FPW_HW_FILTER (the texture unit filters: the explicit fast option),
//   FPW_GATHER + FPW_CHANNELS (order 1 through textureGather, see below),
//   FPW_HOT_STAGES (rows forwarded as flat varyings, see fpw_row),
//   FPW_ACCUMULATE / FPW_OUT_INT (the fragment output kind, see fpw_emit).
// The per-draw values the sampler and the output read (fpw_src_size,
// fpw_cval, ...) are declared from the list in per_draw.glsl.

#ifdef FPW_GATHER
// textureGather with a component argument (GLSL 4.00 core).
#extension GL_ARB_gpu_shader5 : require
#endif

// The parameter block: row 0 header, then the stages (params.py docstring).
// std140 gives an array of vec4 a stride of 16 bytes: no padding traps.
layout(std140) uniform FpiwarpParams {
    vec4 fpw_rows[FPW_MAX_ROWS];
};

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

// A quiet NaN from its bits: 0.0 / 0.0 may be folded away by a compiler.
float fpw_nan() { return uintBitsToFloat(0x7fc00000u); }

bool fpw_finite(vec2 v) {
    return !(any(isnan(v)) || any(isinf(v)));
}

// A source position counts as outside (cval) unless finite and within
// FPW_COORD_LIMIT of the origin in x and y, like _sampling.sample.
bool fpw_in_range(vec2 v) {
    return fpw_finite(v) && all(lessThanEqual(abs(v), vec2(FPW_COORD_LIMIT)));
}

// ---- complex arithmetic ---------------------------------------------------
vec2 fpw_cmul(vec2 a, vec2 b) { return vec2(a.x * b.x - a.y * b.y, a.x * b.y + a.y * b.x); }
vec2 fpw_conj(vec2 a) { return vec2(a.x, -a.y); }
vec2 fpw_cdiv(vec2 a, vec2 b) {
    float d = b.x * b.x + b.y * b.y;
    return vec2(a.x * b.x + a.y * b.y, a.y * b.x - a.x * b.y) / d;
}

// ---- cores -----------------------------------------------------------------
// _tps: the thin-plate spline core and its Wirtinger derivatives at p.
void fpw_tps(vec2 p, int base, int n, out vec2 val, out vec2 dz, out vec2 dzb) {
    vec4 l12 = fpw_row(base + FPW_ROW_L12);
    vec2 l3 = fpw_row(base + FPW_ROW_L3).xy;
    val = fpw_cmul(l12.xy, p) + fpw_cmul(l12.zw, fpw_conj(p)) + l3;
    dz = l12.xy;
    dzb = l12.zw;
    for (int j = 0; j < n; ++j) {
        vec4 cb = fpw_rows[base + FPW_ROW_CENTERS + j];  // center c, weight b
        vec2 d = p - cb.xy;
        float r2 = d.x * d.x + d.y * d.y;
        float lg = r2 > 0.0 ? log(r2) : 0.0;
        val += cb.zw * (0.5 * r2 * lg);
        vec2 g = 0.5 * cb.zw * (lg + 1.0);
        dz += fpw_cmul(g, fpw_conj(d));
        dzb += fpw_cmul(g, d);
    }
}

// _newton: solve TPS(x) = target from the inverse of the affine part.
// A point stops moving once it is within tol (like the reference's
// per-point `done`); not converged after `iters` steps gives NaN.
vec2 fpw_newton(vec2 target, int base, int n, int iters, float tol) {
    vec4 mu12 = fpw_rows[base + FPW_ROW_MU12];
    vec2 mu3 = fpw_rows[base + FPW_ROW_MU3].xy;
    vec2 x = fpw_cmul(mu12.xy, target) + fpw_cmul(mu12.zw, fpw_conj(target)) + mu3;
    vec2 val, dz, dzb;
    bool done = false;
    for (int it = 0; it < iters; ++it) {
        fpw_tps(x, base, n, val, dz, dzb);
        vec2 res = val - target;
        done = length(res) <= tol;
        if (done) break;
        float det = dot(dz, dz) - dot(dzb, dzb);
        vec2 step = (fpw_cmul(fpw_conj(dz), res) - fpw_cmul(dzb, fpw_conj(res))) / det;
        x = x - step;
    }
    if (!done) {  // the reference's for-else: check the last iterate
        fpw_tps(x, base, n, val, dz, dzb);
        done = length(val - target) <= tol;
    }
    return done ? x : vec2(fpw_nan());
}

// ---- one stage and the whole map -----------------------------------------
// _evaluate_stage: regions, pre-Möbius, core, post-Möbius. `core` and
// `n_regions` are arguments so that a program specialized to one kind of
// map can pass constants (the compiler then drops the other cores and
// reads the block at fixed offsets); the values still come from the block.
vec2 fpw_stage_of(vec2 z, int base, int core, int n_regions) {
    vec4 header = fpw_rows[base + FPW_ROW_HEADER];
    int n = int(header.y);
    int iters = int(header.w);
    float best = 0.0;
    vec2 outside = vec2(fpw_nan());
    for (int r = 0; r < n_regions; ++r) {
        vec4 on = fpw_rows[base + FPW_ROW_REGIONS + 2 * r];     // origin, normal
        vec4 ab = fpw_rows[base + FPW_ROW_REGIONS + 2 * r + 1]; // a, b
        float depth = fpw_cmul(z - on.xy, fpw_conj(on.zw)).x;
        if (depth > best) {
            best = depth;
            outside = fpw_cmul(ab.xy, z) + ab.zw;
        }
    }
    if (best > 0.0) return outside;  // the reference's final where(best > 0, ...)
    vec4 pre = fpw_row(base + FPW_ROW_PRE);      // q1, s1
    vec4 scale = fpw_row(base + FPW_ROW_SCALE);  // k1, k2
    vec4 post = fpw_row(base + FPW_ROW_POST);    // s2, q2
    vec2 u = z - pre.xy;
    vec2 p = fpw_cdiv(fpw_cmul(scale.xy, u), vec2(1.0, 0.0) - fpw_cmul(pre.zw, u));
    if (core == FPW_CORE_AFFINE) {
        vec4 l12 = fpw_row(base + FPW_ROW_L12);
        vec2 l3 = fpw_row(base + FPW_ROW_L3).xy;
        p = fpw_cmul(l12.xy, p) + fpw_cmul(l12.zw, fpw_conj(p)) + l3;
    } else if (core == FPW_CORE_TPS) {
        vec2 dz, dzb;
        fpw_tps(p, base, n, p, dz, dzb);
    } else {
        p = fpw_newton(p, base, n, iters, fpw_row(base + FPW_ROW_L3).z);
    }
    return post.zw + fpw_cdiv(fpw_cmul(scale.zw, p), vec2(1.0, 0.0) - fpw_cmul(post.xy, p));
}

// One stage with its kind read from the block header (any map).
vec2 fpw_stage(vec2 z, int base) {
    vec4 header = fpw_rows[base + FPW_ROW_HEADER];
    return fpw_stage_of(z, base, int(header.x), int(header.z));
}

// evaluate: the stages in order. A program specialized to one kind of map
// gets FPW_STAGES from the host: a list of
//   z = fpw_stage_of(z, base, core, n_regions);
// with constants, one per stage (the same evaluation, unrolled).
vec2 fpw_map(vec2 z) {
#ifdef FPW_STAGES
    FPW_STAGES
#else
    int n_stages = int(fpw_rows[0].x);
    for (int k = 0; k < n_stages; ++k) {
        z = fpw_stage(z, 1 + k * FPW_STAGE_ROWS);
    }
#endif
    return z;
}

#ifdef FPW_WITH_SAMPLER
#include "per_draw.glsl"
FPW_DECLARE_PER_DRAW

// ---- software sampling (_sampling.py) -------------------------------------
// Integer images are integer textures read with texelFetch: weights and
// sums are computed here in float, never by the texture unit.
// FPW_GATHER_C(uv, c): channel c of the 2×2 texels around uv, as floats.
#if defined(FPW_INT_TEXTURE)
uniform usampler2D fpw_src;
vec4 fpw_fetch(ivec2 ij) { return vec4(texelFetch(fpw_src, ij, 0)); }
#define FPW_GATHER_C(uv, c) vec4(textureGather(fpw_src, uv, c))
#elif defined(FPW_UNORM_TEXTURE)
// uint8 as a normalized texture: texel v reads as v / 255 (the common,
// fastest texture format of software rasterizers); * 255 gives v back to
// within 1e-5, far below the rounding step.
uniform sampler2D fpw_src;
vec4 fpw_fetch(ivec2 ij) { return texelFetch(fpw_src, ij, 0) * FPW_UNORM_TEXTURE; }
#define FPW_GATHER_C(uv, c) (textureGather(fpw_src, uv, c) * FPW_UNORM_TEXTURE)
#else
uniform sampler2D fpw_src;
vec4 fpw_fetch(ivec2 ij) { return texelFetch(fpw_src, ij, 0); }
#define FPW_GATHER_C(uv, c) textureGather(fpw_src, uv, c)
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
    if (FPW_MODE == 0 || FPW_MODE == 1) return clamp(i, 0, n - 1);
    if (FPW_MODE == 3) return fpw_posmod(i, n);
    if (n == 1) return 0;
    int period = 2 * (n - 1);
    int m = fpw_posmod(i, period);
    return m >= n ? period - m : m;
}

// The texel at border-treated indices (col, row); `inside` tells whether
// the tap's own indices were inside the image ('constant' mode: cval).
vec4 fpw_texel(int col, int row, bool inside) {
    if (FPW_MODE == 0 && !inside) return fpw_cval_term();
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
vec4 fpw_sample(vec2 pos) {
    if (!fpw_in_range(pos)) return fpw_cval;
    pos = clamp(pos, vec2(-FPW_COORD_LIMIT), vec2(FPW_COORD_LIMIT));
    return fpw_hw_scale * texture(fpw_src, (pos + 0.5) / vec2(fpw_src_size));
}
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
#if FPW_MODE == 3
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
#if FPW_MODE == 0
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
#include "pack.glsl"
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
#else
layout(location = 0) out vec4 fpw_frag;
void fpw_emit(vec4 v) { fpw_frag = v * fpw_out_scale; }
#endif
#endif  // FPW_WITH_SAMPLER
