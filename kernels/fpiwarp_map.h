/* fpiwarp_map.h: the shared OpenCL C math of fpiwarp.
 *
 * Mirrors, line by line, two numpy references:
 *   - fpiwarp/params.py `evaluate`: one parameter block (rows of 4 floats,
 *     layout in that module's docstring) applied stage after stage:
 *     regions, pre-Möbius, core (affine / TPS / Newton inverse of the TPS),
 *     post-Möbius;
 *   - fpiwarp/_sampling.py `sample` and `to_dtype`: orders 0/1/3, border
 *     modes constant/edge/reflect/wrap on each tap's integer index,
 *     positions not finite or beyond 2^24 px give cval, integer outputs
 *     floor(v + 0.5) clipped.
 *
 * Everything is float32: the block is solved in float64 on the host and
 * only evaluated here. Complex numbers are a struct of two scalars rather
 * than float2, and selections are branch-free where the reference uses
 * np.where: CPU drivers (PoCL) vectorize across work-items only code made
 * of scalar operations without inner loops.
 *
 * Build-time defines (all optional for the map part):
 *   FW_KIND_k = "core, n_centers, n_regions, newton_iters", one for each
 *     stage k = 0, 1, ... (at most 8): the header rows of the block's
 *     stages, its "kind". With them the stage loop unrolls and branches
 *     fold away; without them fw_map reads the kind from the block at run
 *     time. Values (coefficients) are never build options.
 *   FW_ORDER 0|1|3, FW_MODE 0..3, FW_T, FW_C, FW_INT, FW_TOP, FW_VN:
 *     sampling (see the block guarded by FW_T at the end).
 */
#ifndef FPIWARP_MAP_H
#define FPIWARP_MAP_H

/* every helper is inlined: calls left in a kernel stop CPU vectorization */
#define FW_FN static inline __attribute__((always_inline))

/* ---- block layout: keep in sync with fpiwarp/params.py ---------------- */
#define FW_STAGE_ROWS 76
#define FW_ROW_HEADER 0
#define FW_ROW_PRE 1
#define FW_ROW_SCALE 2
#define FW_ROW_POST 3
#define FW_ROW_L12 4
#define FW_ROW_L3 5
#define FW_ROW_MU12 6
#define FW_ROW_MU3 7
#define FW_ROW_REGIONS 8
#define FW_ROW_CENTERS 12
#define FW_CORE_AFFINE 0
#define FW_CORE_TPS 1
#define FW_CORE_TPS_INVERSE 2
#define FW_MAX_REGIONS 2

/* The block as the kernels receive it, and one stage's rows as floats. */
typedef __constant const float4 *fw_block_t;
typedef __constant const float *fw_rows_t;

/* ---- complex arithmetic on (re, im) ------------------------------------ */
typedef struct {
    float re, im;
} fw_c;

FW_FN fw_c fw_cx(float re, float im)
{
    fw_c r = {re, im};
    return r;
}

/* the complex number in columns (col, col + 1) of row `row` */
FW_FN fw_c fw_at(fw_rows_t rows, int row, int col)
{
    return fw_cx(rows[4 * row + col], rows[4 * row + col + 1]);
}

FW_FN fw_c fw_add(fw_c a, fw_c b) { return fw_cx(a.re + b.re, a.im + b.im); }
FW_FN fw_c fw_sub(fw_c a, fw_c b) { return fw_cx(a.re - b.re, a.im - b.im); }
FW_FN fw_c fw_conj(fw_c a) { return fw_cx(a.re, -a.im); }
FW_FN fw_c fw_scale(fw_c a, float s) { return fw_cx(a.re * s, a.im * s); }
FW_FN float fw_abs2(fw_c a) { return a.re * a.re + a.im * a.im; }

FW_FN fw_c fw_mul(fw_c a, fw_c b)
{
    return fw_cx(a.re * b.re - a.im * b.im, a.re * b.im + a.im * b.re);
}

/* a / b as a conj(b) / |b|^2: one division for both parts */
FW_FN fw_c fw_div(fw_c a, fw_c b)
{
    return fw_scale(fw_mul(a, fw_conj(b)), 1.0f / fw_abs2(b));
}

/* np.where(cond, a, b) */
FW_FN fw_c fw_select(bool cond, fw_c a, fw_c b)
{
    return fw_cx(cond ? a.re : b.re, cond ? a.im : b.im);
}

/* l1 p + l2 conj(p) + l3, the R-linear part */
FW_FN fw_c fw_rlinear(fw_c p, fw_c l1, fw_c l2, fw_c l3)
{
    return fw_add(fw_add(fw_mul(l1, p), fw_mul(l2, fw_conj(p))), l3);
}

/* ---- TPS core (params._tps) -------------------------------------------- */
/* The TPS core at p, and its Wirtinger derivatives in *dz, *dzb. */
FW_FN fw_c fw_tps(fw_c p, fw_rows_t rows, int n, fw_c *dz, fw_c *dzb)
{
    fw_c l1 = fw_at(rows, FW_ROW_L12, 0), l2 = fw_at(rows, FW_ROW_L12, 2), l3 = fw_at(rows, FW_ROW_L3, 0);
    fw_c val = fw_rlinear(p, l1, l2, l3);
    *dz = l1;
    *dzb = l2;
    for (int j = 0; j < n; ++j) {
        fw_c c = fw_at(rows, FW_ROW_CENTERS + j, 0), b = fw_at(rows, FW_ROW_CENTERS + j, 2);
        fw_c d = fw_sub(p, c);
        float r2 = fw_abs2(d);
        float lg = r2 > 0.0f ? log(r2) : 0.0f;
        val = fw_add(val, fw_scale(b, 0.5f * r2 * lg));
        fw_c g = fw_scale(b, 0.5f * (lg + 1.0f));
        *dz = fw_add(*dz, fw_mul(g, fw_conj(d)));
        *dzb = fw_add(*dzb, fw_mul(g, d));
    }
    return val;
}

/* ---- Newton inverse of the TPS core (params._newton) ------------------- */
/* Per point this is the reference exactly: a converged point keeps its x
 * (np.where(done, x, x - step)), so checking once more after the last
 * step gives the same verdict as the reference's early exit. */
FW_FN fw_c fw_newton(fw_c target, fw_rows_t rows, int n, int iters, float tol)
{
    fw_c mu1 = fw_at(rows, FW_ROW_MU12, 0), mu2 = fw_at(rows, FW_ROW_MU12, 2), mu3 = fw_at(rows, FW_ROW_MU3, 0);
    fw_c x = fw_rlinear(target, mu1, mu2, mu3);
    fw_c dz, dzb;
    for (int k = 0; k < iters; ++k) {
        fw_c res = fw_sub(fw_tps(x, rows, n, &dz, &dzb), target);
        bool done = sqrt(fw_abs2(res)) <= tol;
        float det = fw_abs2(dz) - fw_abs2(dzb);
        fw_c step = fw_scale(fw_sub(fw_mul(fw_conj(dz), res), fw_mul(dzb, fw_conj(res))), 1.0f / det);
        x = fw_select(done, x, fw_sub(x, step));
    }
    fw_c res = fw_sub(fw_tps(x, rows, n, &dz, &dzb), target);
    bool done = sqrt(fw_abs2(res)) <= tol;
    return fw_select(done, x, fw_cx(NAN, NAN));
}

/* region r of a stage: the deepest region containing z wins */
FW_FN void fw_region(fw_rows_t rows, int r, fw_c z, float *best, fw_c *outside)
{
    fw_c o = fw_at(rows, FW_ROW_REGIONS + 2 * r, 0), nrm = fw_at(rows, FW_ROW_REGIONS + 2 * r, 2);
    fw_c a = fw_at(rows, FW_ROW_REGIONS + 2 * r + 1, 0), b = fw_at(rows, FW_ROW_REGIONS + 2 * r + 1, 2);
    float depth = fw_mul(fw_sub(z, o), fw_conj(nrm)).re;
    bool win = depth > *best;
    *best = win ? depth : *best;
    *outside = fw_select(win, fw_add(fw_mul(a, z), b), *outside);
}

/* ---- one stage (params._evaluate_stage) -------------------------------- */
/* core, n, n_regions, iters: the stage's header row (compile-time
 * constants when the kind is known, so the unused branches fold away). */
FW_FN fw_c fw_stage_kind(fw_rows_t rows, fw_c z, int core, int n, int n_regions, int iters)
{
    float best = 0.0f;
    fw_c outside = fw_cx(NAN, NAN);
    /* for r < n_regions, written out (at most FW_MAX_REGIONS = 2) */
    if (n_regions > 0)
        fw_region(rows, 0, z, &best, &outside);
    if (n_regions > 1)
        fw_region(rows, 1, z, &best, &outside);
    fw_c u = fw_sub(z, fw_at(rows, FW_ROW_PRE, 0));
    fw_c p = fw_div(fw_mul(fw_at(rows, FW_ROW_SCALE, 0), u), fw_sub(fw_cx(1.0f, 0.0f), fw_mul(fw_at(rows, FW_ROW_PRE, 2), u)));
    if (core == FW_CORE_AFFINE) {
        p = fw_rlinear(p, fw_at(rows, FW_ROW_L12, 0), fw_at(rows, FW_ROW_L12, 2), fw_at(rows, FW_ROW_L3, 0));
    } else if (core == FW_CORE_TPS) {
        fw_c dz, dzb;
        p = fw_tps(p, rows, n, &dz, &dzb);
    } else {
        p = fw_newton(p, rows, n, iters, rows[4 * FW_ROW_L3 + 2]);
    }
    fw_c w = fw_add(fw_at(rows, FW_ROW_POST, 2),
                    fw_div(fw_mul(fw_at(rows, FW_ROW_SCALE, 2), p), fw_sub(fw_cx(1.0f, 0.0f), fw_mul(fw_at(rows, FW_ROW_POST, 0), p))));
    return fw_select(best > 0.0f, outside, w);
}

/* the rows of stage k of a block */
FW_FN fw_rows_t fw_stage_rows(fw_block_t block, int k)
{
    return (fw_rows_t)(block + 1 + k * FW_STAGE_ROWS);
}

/* one stage, its kind read from its header row */
FW_FN fw_c fw_stage(fw_rows_t rows, fw_c z)
{
    return fw_stage_kind(rows, z, (int)rows[0], (int)rows[1], (int)rows[2], (int)rows[3]);
}

/* ---- the whole block (params.evaluate) --------------------------------- */
FW_FN fw_c fw_map(fw_block_t block, fw_c z)
{
#ifdef FW_KIND_0
#define FW_APPLY(k, kind) z = fw_stage_kind(fw_stage_rows(block, k), z, kind)
    FW_APPLY(0, FW_KIND_0);
#ifdef FW_KIND_1
    FW_APPLY(1, FW_KIND_1);
#endif
#ifdef FW_KIND_2
    FW_APPLY(2, FW_KIND_2);
#endif
#ifdef FW_KIND_3
    FW_APPLY(3, FW_KIND_3);
#endif
#ifdef FW_KIND_4
    FW_APPLY(4, FW_KIND_4);
#endif
#ifdef FW_KIND_5
    FW_APPLY(5, FW_KIND_5);
#endif
#ifdef FW_KIND_6
    FW_APPLY(6, FW_KIND_6);
#endif
#ifdef FW_KIND_7
    FW_APPLY(7, FW_KIND_7);
#endif
#undef FW_APPLY
#else
    int n_stages = (int)block[0].x;
    for (int k = 0; k < n_stages; ++k)
        z = fw_stage(fw_stage_rows(block, k), z);
#endif
    return z;
}

/* ---- sampling (fpiwarp/_sampling.py) ------------------------------------ */
#define FW_MODE_CONSTANT 0
#define FW_MODE_EDGE 1
#define FW_MODE_REFLECT 2
#define FW_MODE_WRAP 3
/* source positions beyond 2^24 px in x or y (or not finite) are outside */
#define FW_COORD_LIMIT 16777216.0f

/* The rest needs the image type: FW_T (uchar, ushort or float) with FW_C
 * interleaved channels, FW_INT 1 for integer types and FW_TOP their
 * largest value, FW_ORDER and FW_MODE; FW_VN (1 or 8, default 1), the
 * number of pixels one work-item samples at once.
 *
 * Sampling is written for FW_VN lanes with OpenCL vector types (floatN,
 * intN; float and int when FW_VN is 1). On CPUs the host asks for 8:
 * PoCL vectorizes across work-items only loop bodies without vector
 * instructions, and before it does, LLVM's SLP vectorizer pairs the
 * sampling's many alike scalar operations (x and y, channels, taps) into
 * 2-lane vectors, which stop it; explicit 8-lane code does not depend on
 * either. Taps, channels and lanes are written out by the FW_EACH_*
 * macros into separate variables (x0, x1, ...; acc0, ...). */
#ifdef FW_T
#ifndef FW_VN
#define FW_VN 1
#endif
#if FW_VN == 1
typedef float fw_fv;
typedef int fw_iv;
typedef uint fw_uv;
#define FW_EACH_LANE(X, a) X(0, a)
#define FW_LANE(v, k) (v)
#define FW_VLOAD(p) (*(p))
#define FW_CONVERT(type, v) convert_##type(v)
#elif FW_VN == 8
typedef float8 fw_fv;
typedef int8 fw_iv;
typedef uint8 fw_uv;
#define FW_EACH_LANE(X, a) X(0, a) X(1, a) X(2, a) X(3, a) X(4, a) X(5, a) X(6, a) X(7, a)
#define FW_LANE(v, k) (v).s##k
#define FW_VLOAD(p) vload8(0, p)
#define FW_CONVERT(type, v) convert_##type##8(v)
#else
#error "FW_VN must be 1 or 8"
#endif
/* expr(k), a scalar expression of lane k, for every lane as one vector */
#if FW_VN == 1
#define FW_GATHER(type, expr) ((type)(expr(0)))
#else
#define FW_GATHER(type, expr) ((type)(expr(0) FW_GATHER_REST(expr)))
#define FW_GATHER_REST(expr) , expr(1), expr(2), expr(3), expr(4), expr(5), expr(6), expr(7)
#endif

#if FW_ORDER == 0
#define FW_EACH_TAP(X, a) X(0, a)
#define FW_EACH_ROW(X) X(0)
#elif FW_ORDER == 1
#define FW_EACH_TAP(X, a) X(0, a) X(1, a)
#define FW_EACH_ROW(X) X(0) X(1)
#else
#define FW_EACH_TAP(X, a) X(0, a) X(1, a) X(2, a) X(3, a)
#define FW_EACH_ROW(X) X(0) X(1) X(2) X(3)
#endif
#if FW_C == 1
#define FW_EACH_C(X, a) X(0, a)
#elif FW_C == 2
#define FW_EACH_C(X, a) X(0, a) X(1, a)
#elif FW_C == 3
#define FW_EACH_C(X, a) X(0, a) X(1, a) X(2, a)
#else
#define FW_EACH_C(X, a) X(0, a) X(1, a) X(2, a) X(3, a)
#endif

/* FW_WORD_BITS: where a pixel's channels fit in 32 bits (uchar with up to
 * 4 channels, ushort with up to 2) on a little-endian device, a tap is one
 * 32-bit load, channel k being bits [k * FW_WORD_BITS, ...). The load may
 * read up to 3 bytes past the image: the host allocates 4 more. */
#if defined(__ENDIAN_LITTLE__) && FW_INT && FW_TOP == 255 && FW_C <= 4
#define FW_WORD_BITS 8
#elif defined(__ENDIAN_LITTLE__) && FW_INT && FW_TOP == 65535 && FW_C <= 2
#define FW_WORD_BITS 16
#else
#define FW_WORD_BITS 0
#endif
#if FW_WORD_BITS
/* a packed struct: the portable unaligned 32-bit load */
typedef struct __attribute__((packed)) {
    uint v;
} fw_word;
#endif

/* floor(v) as an int, branch-free; exact for |v| <= 2^24, which
 * fw_sample guarantees (PoCL's floor() has branches) */
FW_FN fw_iv fw_floor(fw_fv v)
{
    fw_iv i = FW_CONVERT(int, v);
    return select(i, i - 1, FW_CONVERT(float, i) > v);
}

/* Python's i mod n, in [0, n) */
FW_FN fw_iv fw_mod(fw_iv i, int n)
{
    fw_iv m = i % n;
    return select(m, m + n, m < 0);
}

FW_FN fw_iv fw_inside(fw_iv i, int n) { return (i >= 0) & (i < n); }

/* _sampling.border_index: a valid index for tap i along an axis of n */
FW_FN fw_iv fw_border(fw_iv i, int n)
{
#if FW_MODE == FW_MODE_WRAP
    return fw_mod(i, n);
#elif FW_MODE == FW_MODE_REFLECT
    int period = max(2 * (n - 1), 1); /* n == 1 gives 0 */
    fw_iv m = fw_mod(i, period);
    return select(m, period - m, m >= n);
#else /* constant and edge clamp; constant also checks fw_inside */
    return clamp(i, 0, n - 1);
#endif
}

/* _sampling._taps: declares the integer tap positions p##0.. and their
 * weights p##w0.. along one axis, for coordinate `coord` */
#if FW_ORDER == 0
#define FW_TAPS_1D(coord, p)                      \
    fw_iv p##0 = fw_floor((coord) + 0.5f);        \
    fw_fv p##w0 = 1.0f;
#else
#define FW_TAPS_1D(coord, p)                      \
    fw_iv p##base = fw_floor(coord);              \
    fw_fv p##t = (coord) - FW_CONVERT(float, p##base); \
    FW_TAPS_1D_REST(p)
#if FW_ORDER == 1
#define FW_TAPS_1D_REST(p)                        \
    fw_iv p##0 = p##base, p##1 = p##0 + 1;        \
    fw_fv p##w0 = 1.0f - p##t, p##w1 = p##t;
#else /* Keys' cubic convolution, a = -0.5 (_sampling._cubic_weights) */
#define FW_TAPS_1D_REST(p)                                                   \
    fw_iv p##1 = p##base, p##0 = p##1 - 1, p##2 = p##1 + 1, p##3 = p##1 + 2; \
    fw_fv p##t2 = p##t * p##t, p##t3 = p##t2 * p##t;                         \
    fw_fv p##w0 = -0.5f * p##t3 + p##t2 - 0.5f * p##t;                      \
    fw_fv p##w1 = 1.5f * p##t3 - 2.5f * p##t2 + 1.0f;                       \
    fw_fv p##w2 = -1.5f * p##t3 + 2.0f * p##t2 + 0.5f * p##t;               \
    fw_fv p##w3 = 0.5f * p##t3 - 0.5f * p##t2;
#endif
#endif

/* The taps of fw_sample: tap (i, j) adds its weight times its value to
 * acc##k for each channel k; a tap's value is one gather per channel, or
 * one gather of 32-bit words for all channels (FW_WORD_BITS). */
#if FW_WORD_BITS
#define FW_TAP_LOAD(at) fw_uv word = FW_GATHER(fw_uv, FW_WORD_AT);
#define FW_WORD_AT(k) ((__global const fw_word *)(img + FW_LANE(at, k)))->v
#define FW_VALUE(k, at) FW_CONVERT(float, (word >> (FW_WORD_BITS * k)) & (uint)FW_TOP)
#else
#define FW_TAP_LOAD(at)
#define FW_VALUE(k, at) FW_GATHER(fw_fv, FW_VALUE_AT_##k)
#define FW_VALUE_AT_0(j) (float)img[FW_LANE(at, j) + 0]
#define FW_VALUE_AT_1(j) (float)img[FW_LANE(at, j) + 1]
#define FW_VALUE_AT_2(j) (float)img[FW_LANE(at, j) + 2]
#define FW_VALUE_AT_3(j) (float)img[FW_LANE(at, j) + 3]
#endif
#if FW_MODE == FW_MODE_CONSTANT
#define FW_CHANNEL(k, _) acc##k += wgt * select((fw_fv)(cval.s##k), FW_VALUE(k, at), in);
#else
#define FW_CHANNEL(k, _) acc##k += wgt * FW_VALUE(k, at);
#endif
#define FW_INDEX(i, _)                               \
    fw_iv col##i = fw_border(x##i, w) * FW_C;        \
    fw_iv col_in##i = fw_inside(x##i, w);            \
    fw_iv row##i = fw_border(y##i, h) * (w * FW_C);  \
    fw_iv row_in##i = fw_inside(y##i, h);
#define FW_TAP(i, j)                                 \
    {                                                \
        fw_fv wgt = y##w##j * x##w##i;               \
        fw_iv at = row##j + col##i;                  \
        fw_iv in = row_in##j & col_in##i;            \
        FW_TAP_LOAD(at)                              \
        FW_EACH_C(FW_CHANNEL, _)                     \
    }
#define FW_ROW_TAPS(j) FW_EACH_TAP(FW_TAP, j)
/* channel values at FW_VN pixels; c##k for k < FW_C are used */
typedef struct {
    fw_fv c0, c1, c2, c3;
} fw_pxv;

/* _sampling.sample at FW_VN positions (sx, sy): the values before
 * rounding. Branch-free: every tap's index is made valid, so its load is
 * unconditional; in constant mode the value is then replaced by cval
 * outside the image. */
FW_FN fw_pxv fw_sample(__global const FW_T *img, int w, int h, fw_fv sx, fw_fv sy, float4 cval)
{
    /* beyond FW_COORD_LIMIT (or NaN) counts as outside: cval */
    fw_iv finite = (fabs(sx) <= FW_COORD_LIMIT) & (fabs(sy) <= FW_COORD_LIMIT);
    fw_fv x = select((fw_fv)0.0f, sx, finite);
    fw_fv y = select((fw_fv)0.0f, sy, finite);
    FW_TAPS_1D(x, x)
    FW_TAPS_1D(y, y)
    FW_EACH_TAP(FW_INDEX, _)
    fw_fv acc0 = 0.0f, acc1 = 0.0f, acc2 = 0.0f, acc3 = 0.0f;
    FW_EACH_ROW(FW_ROW_TAPS)
    fw_pxv out = {select((fw_fv)cval.s0, acc0, finite), select((fw_fv)cval.s1, acc1, finite),
                  select((fw_fv)cval.s2, acc2, finite), select((fw_fv)cval.s3, acc3, finite)};
    return out;
}

/* _sampling.to_dtype: floor(v + 0.5) clipped for integers (clamping first
 * makes the conversion's truncation a floor), as is for floats */
#if FW_INT
typedef fw_iv fw_ov;
#define FW_TO_DTYPE(v) FW_CONVERT(int, clamp((v) + 0.5f, 0.0f, (float)FW_TOP))
#else
typedef fw_fv fw_ov;
#define FW_TO_DTYPE(v) (v)
#endif
#endif /* FW_T */

#endif /* FPIWARP_MAP_H */
