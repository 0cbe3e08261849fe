// The map: the block evaluated at a point, mirroring fpiwarp/block/reference.py
// (evaluate / evaluate_stage / tps_core / newton) line by line, in float32.
// Complex numbers are vec2 (re, im). Reads the block through block.glsl.
// Part of fpiwarp.glsl.

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
// tps_pairs.tps_pairs_core: the n / 2 pairs of n center rows at p, added
// to val, dz, dzb (see fpiwarp/block/tps_pairs.py for the formulas);
// deriv false: val only (a constant: the derivative terms fold away).
void fpw_tps_pairs(vec2 p, int base, int n, bool deriv, inout vec2 val, inout vec2 dz, inout vec2 dzb) {
    for (int j = 0; j < n; j += 2) {
        vec4 cw = fpw_rows[base + FPW_ROW_CENTERS + j];      // center c, summed weight W
        vec4 db = fpw_rows[base + FPW_ROW_CENTERS + j + 1];  // offset d, weight b2
        vec2 q = p - cw.xy;
        vec2 q2 = q - db.xy;
        float a = dot(q, q);
        float b = dot(q2, q2);
        float e = dot(db.xy, db.xy) - 2.0 * dot(q, db.xy);
        bool near_a = a <= b;
        float s = near_a ? a : b;
        float m = near_a ? b : a;
        // tps_pairs.pair_logs: log(max) from the series where it holds
        float ae = abs(e);
        bool ok = s > 0.0 && ae <= 0.25 * s;
        float t = ok ? ae / (2.0 * s + ae) : 0.0;
        float t2 = t * t;
        float series = 2.0 * t * (1.0 + t2 * (0.33333333 + t2 * (0.2 + t2 * 0.14285714)));
        float ls = s > 0.0 ? log(s) : 0.0;
        float lm = ls + series;
        if (!ok) {
            lm = m > 0.0 ? log(m) : 0.0;
        }
        float mag = ok ? series : lm - ls;
        float big_l = e < 0.0 ? -mag : mag;
        float la = near_a ? ls : lm;
        val += cw.zw * (0.5 * a * la) + db.zw * (0.5 * (e * lm + s * big_l));
        if (!deriv) continue;
        float g1 = 0.5 * (la + 1.0);
        float gn = 0.5 * (lm + 1.0);
        vec2 qn = near_a ? q : q2;
        dz += fpw_cmul(cw.zw, fpw_conj(q) * g1) + fpw_cmul(db.zw, fpw_conj(qn) * (0.5 * big_l) - fpw_conj(db.xy) * gn);
        dzb += fpw_cmul(cw.zw, q * g1) + fpw_cmul(db.zw, qn * (0.5 * big_l) - db.xy * gn);
    }
}

// _tps: the thin-plate spline core and its Wirtinger derivatives at p
// (paired: the center rows are pairs, FPW_CORE_TPS_PAIRS*); deriv false:
// its value only (dz, dzb then hold the affine part's).
void fpw_tps_d(vec2 p, int base, int n, bool paired, bool deriv, out vec2 val, out vec2 dz, out vec2 dzb) {
    vec4 l12 = fpw_row(base + FPW_ROW_L12);
    vec2 l3 = fpw_row(base + FPW_ROW_L3).xy;
    val = fpw_cmul(l12.xy, p) + fpw_cmul(l12.zw, fpw_conj(p)) + l3;
    dz = l12.xy;
    dzb = l12.zw;
    if (paired) {
        fpw_tps_pairs(p, base, n, deriv, val, dz, dzb);
        return;
    }
    for (int j = 0; j < n; ++j) {
        vec4 cb = fpw_rows[base + FPW_ROW_CENTERS + j];  // center c, weight b
        vec2 d = p - cb.xy;
        float r2 = d.x * d.x + d.y * d.y;
        float lg = r2 > 0.0 ? log(r2) : 0.0;
        val += cb.zw * (0.5 * r2 * lg);
        if (!deriv) continue;
        vec2 g = 0.5 * cb.zw * (lg + 1.0);
        dz += fpw_cmul(g, fpw_conj(d));
        dzb += fpw_cmul(g, d);
    }
}

void fpw_tps(vec2 p, int base, int n, bool paired, out vec2 val, out vec2 dz, out vec2 dzb) {
    fpw_tps_d(p, base, n, paired, true, val, dz, dzb);
}

// reference.seed_correction: the seed table's bilinear correction at t,
// added to the R-linear seed (f clamped to [0, SEED_N - 1], NaN: 0).
vec2 fpw_seed_node(int base, int k) {
    vec4 r = fpw_rows[base + FPW_ROW_SEED_GRID + k / 2];
    return (k % 2) == 0 ? r.xy : r.zw;
}

// the seed table's cell of t (its box: lo, g): the clamped node
// coordinate f (NaN: 0), its cell (i, j) and the fractions f - (i, j)
ivec2 fpw_seed_cell(vec2 t, vec4 box, out vec2 frac) {
    vec2 f = (t - box.xy) * box.zw;
    f.x = f.x > 0.0 ? min(f.x, float(FPW_SEED_N - 1)) : 0.0;
    f.y = f.y > 0.0 ? min(f.y, float(FPW_SEED_N - 1)) : 0.0;
    ivec2 ij = ivec2(min(int(f.x), FPW_SEED_N - 2), min(int(f.y), FPW_SEED_N - 2));
    frac = vec2(f.x - float(ij.x), f.y - float(ij.y));
    return ij;
}

vec2 fpw_seed_correction(vec2 t, int base) {
    vec2 frac;
    ivec2 ij = fpw_seed_cell(t, fpw_rows[base + FPW_ROW_SEED], frac);
    int k = ij.y * FPW_SEED_N + ij.x;
    vec2 c00 = fpw_seed_node(base, k);
    vec2 c01 = fpw_seed_node(base, k + 1);
    vec2 c10 = fpw_seed_node(base, k + FPW_SEED_N);
    vec2 c11 = fpw_seed_node(base, k + FPW_SEED_N + 1);
    vec2 bottom = c00 + (c01 - c00) * frac.x;
    vec2 top = c10 + (c11 - c10) * frac.x;
    return bottom + (top - bottom) * frac.y;
}

// reference.seed_corner: the preimage the seed table holds at corner c
// (0..3: reference.RESTART_CORNERS, (c & 1, c >> 1) added to the cell) of
// t's cell, the R-linear inverse of the node plus its correction.
vec2 fpw_seed_corner(vec2 t, int base, vec4 mu12, vec2 mu3, int c) {
    vec4 box = fpw_rows[base + FPW_ROW_SEED];
    vec2 frac;
    ivec2 ij = fpw_seed_cell(t, box, frac);
    int i = ij.x + c % 2;
    int j = ij.y + c / 2;
    vec2 node = vec2(box.x + float(i) / box.z, box.y + float(j) / box.w);
    return fpw_cmul(mu12.xy, node) + fpw_cmul(mu12.zw, fpw_conj(node)) + mu3 + fpw_seed_node(base, j * FPW_SEED_N + i);
}

// ---- a warp's coarse pass (fpiwarp/block/coarse.py) ---------------------
// FPW_COARSE (a per-pixel warp or preview of a map with a Newton core):
// the coarse pass's node records are in two RGBA32F textures, node (i, j)
// at texel (i, j): fpw_coarse_xa (x, a), fpw_coarse_b (b, unused); node
// (i, j) lies at window pixel fpw_coarse_origin + COARSE_STEP (i, j) (see
// glsl/backend/coarse.frag). FPW_PIXEL_MAP(xy) is fpw_map(xy) of the
// fragment's own pixel: under FPW_COARSE it seeds the block's first
// Newton stage (fpw_seed_pending, read and cleared by that stage, whether
// a region takes the pixel or not) from its four nodes. A batch
// (FPW_BATCH) holds image k's ny = fpw_coarse_rows rows of nodes at texel
// rows [k ny, (k + 1) ny) (fpw_batch.y = k).
#ifdef FPW_COARSE
uniform sampler2D fpw_coarse_xa;
uniform sampler2D fpw_coarse_b;
uniform ivec2 fpw_coarse_origin;
bool fpw_seed_pending = false;
ivec2 fpw_seed_pixel;
#ifdef FPW_BATCH
uniform int fpw_coarse_rows;
#define FPW_COARSE_NODES ivec2(textureSize(fpw_coarse_xa, 0).x, fpw_coarse_rows)
#define FPW_COARSE_FIRST ivec2(0, fpw_batch.y * fpw_coarse_rows)
#else
#define FPW_COARSE_NODES textureSize(fpw_coarse_xa, 0)
#define FPW_COARSE_FIRST ivec2(0)
#endif

// coarse.pixel_seeds: the bilinear interpolation of the four nodes' records
void fpw_coarse_seed(out vec2 x, out vec2 a, out vec2 b) {
    ivec2 nodes = FPW_COARSE_NODES;
    ivec2 ij = min(fpw_seed_pixel / FPW_COARSE_STEP, nodes - 2);
    vec2 f = vec2(fpw_seed_pixel - FPW_COARSE_STEP * ij) / float(FPW_COARSE_STEP);
    ivec2 at = ij + FPW_COARSE_FIRST;
    vec4 xa00 = texelFetch(fpw_coarse_xa, at, 0), xa01 = texelFetch(fpw_coarse_xa, at + ivec2(1, 0), 0);
    vec4 xa10 = texelFetch(fpw_coarse_xa, at + ivec2(0, 1), 0), xa11 = texelFetch(fpw_coarse_xa, at + ivec2(1, 1), 0);
    vec2 b00 = texelFetch(fpw_coarse_b, at, 0).xy, b01 = texelFetch(fpw_coarse_b, at + ivec2(1, 0), 0).xy;
    vec2 b10 = texelFetch(fpw_coarse_b, at + ivec2(0, 1), 0).xy, b11 = texelFetch(fpw_coarse_b, at + ivec2(1, 1), 0).xy;
    vec4 xa_bottom = xa00 + f.x * (xa01 - xa00), xa_top = xa10 + f.x * (xa11 - xa10);
    vec4 xa = xa_bottom + f.y * (xa_top - xa_bottom);
    vec2 b_bottom = b00 + f.x * (b01 - b00), b_top = b10 + f.x * (b11 - b10);
    x = xa.xy;
    a = xa.zw;
    b = b_bottom + f.y * (b_top - b_bottom);
}

vec2 fpw_map(vec2 z);
vec2 fpw_map_seeded(vec2 z, ivec2 pixel) {
    fpw_seed_pending = true;
    fpw_seed_pixel = pixel;
    return fpw_map(z);
}
#define FPW_PIXEL_MAP(xy) fpw_map_seeded(xy, ivec2(FPW_FRAG_XY) - fpw_coarse_origin)
#else
#define FPW_PIXEL_MAP(xy) fpw_map(xy)
#endif

// _newton: solve TPS(x) = target from the inverse of the affine part plus
// the seed table's correction.
// A point stops moving once it is within tol (like the reference's
// per-point `done`); not converged after `iters` steps gives NaN.
// seeded (FPW_COARSE only): the pixel's coarse seed x0 first, where the
// spline's value there (no derivatives) lies within tol of the target the
// answer is x0 - (a r + b conj(r)), r the residual (reference.newton);
// elsewhere the solve as without a seed.
vec2 fpw_newton_seeded(vec2 target, int base, int n, bool paired, int iters, float tol, bool seeded) {
    vec2 val, dz, dzb;
    bool done = false;
    vec2 x = vec2(0.0);
#ifdef FPW_COARSE
    if (seeded) {
        vec2 x0, a, b;
        fpw_coarse_seed(x0, a, b);
        fpw_tps_d(x0, base, n, paired, false, val, dz, dzb);
        vec2 r = val - target;
        done = length(r) <= tol;  // NaN: false
        x = x0 - (fpw_cmul(a, r) + fpw_cmul(b, fpw_conj(r)));
    }
#endif
    vec2 start = vec2(0.0), correction = vec2(0.0);
    vec4 mu12 = fpw_rows[base + FPW_ROW_MU12];
    vec2 mu3 = fpw_rows[base + FPW_ROW_MU3].xy;
    if (!done) {
        start = fpw_cmul(mu12.xy, target) + fpw_cmul(mu12.zw, fpw_conj(target)) + mu3;
        correction = fpw_seed_correction(target, base);
        x = start + correction;
    }
    // iters steps, then the reference's for-else (a check of the last
    // iterate) as a last pass of the loop; pixels done (seeded) skip it.
    // (One loop, no if after it: llvmpipe runs an if's body under a mask
    // even where no pixel of its SIMD group takes it; on the benchmark's
    // frame this shape of the seeded solve measured 5-10 % faster than an
    // early return before the loop and its for-else check.)
    // The solve from the table's seed, then, where it fails (the
    // reference's restarts): from the R-linear seed alone where the table's
    // correction is not 0, from the table's preimages at the corners of
    // the target's cell where the stage has a table.
    bool rlinear = correction != vec2(0.0);
    vec4 box = fpw_rows[base + FPW_ROW_SEED];
    int passes = (box.z != 0.0 && box.w != 0.0) ? 6 : (rlinear ? 2 : 1);
    for (int pass = 0; pass < passes && !done; ++pass) {
        bool skip = pass == 1 && !rlinear;  // the same solve again
        if (pass == 1) x = start;
        else if (pass > 1) x = fpw_seed_corner(target, base, mu12, mu3, pass - 2);
        for (int it = 0; it <= iters && !done && !skip; ++it) {
            fpw_tps(x, base, n, paired, val, dz, dzb);
            vec2 res = val - target;
            done = length(res) <= tol;
            if (done || it == iters) break;
            float det = dot(dz, dz) - dot(dzb, dzb);
            vec2 step = (fpw_cmul(fpw_conj(dz), res) - fpw_cmul(dzb, fpw_conj(res))) / det;
            x = x - step;
        }
    }
    return done ? x : vec2(fpw_nan());
}

vec2 fpw_newton(vec2 target, int base, int n, bool paired, int iters, float tol) {
    return fpw_newton_seeded(target, base, n, paired, iters, tol, false);
}

// reference.pre_mobius: step 2 of a stage
vec2 fpw_pre(vec2 z, int base) {
    vec4 pre = fpw_row(base + FPW_ROW_PRE);      // q1, s1
    vec4 scale = fpw_row(base + FPW_ROW_SCALE);  // k1, k2
    vec2 u = z - pre.xy;
    return fpw_cdiv(fpw_cmul(scale.xy, u), vec2(1.0, 0.0) - fpw_cmul(pre.zw, u));
}

// FPW_COARSE_PASS (glsl/backend/coarse.frag): fpw_map of a node stops at
// the block's first Newton stage (regions skipped), which leaves the
// node's record (coarse.coarse_pass) in fpw_node_*: x the solution from
// the table seed (NaN where it fails or the inverse Jacobian is not
// finite), a, b the inverse Jacobian's Wirtinger parts there.
#ifdef FPW_COARSE_PASS
bool fpw_node_done = false;
vec2 fpw_node_x, fpw_node_a, fpw_node_b;
// How far (output units) from a node the pixels that read it lie, set by
// coarse.frag; a node of the block's first stage that one of its regions
// holds deeper than that (and a margin for float32 rounding) is read by no
// pixel the regions leave: its solve is skipped, its record NaN. (It is
// inside a loop, so that on llvmpipe a SIMD group of such nodes runs none
// of it: an if's body runs under a mask, a loop stops when no lane is left.)
float fpw_node_reach = -1.0;

bool fpw_node_unread(vec2 z, int base, int n_regions) {
    bool unread = false;
    for (int r = 0; r < n_regions; ++r) {
        vec4 on = fpw_rows[base + FPW_ROW_REGIONS + 2 * r];  // origin, normal
        float depth = fpw_cmul(z - on.xy, fpw_conj(on.zw)).x;
        float margin = fpw_node_reach + 1e-4 * (length(z) + length(on.xy) + 1.0);
        unread = unread || (fpw_node_reach >= 0.0 && depth > margin * length(on.zw));
    }
    return unread;
}

void fpw_coarse_node(vec2 z, int base, int n, bool paired, int iters) {
    vec2 x = fpw_newton(fpw_pre(z, base), base, n, paired, iters, fpw_row(base + FPW_ROW_L3).z);
    vec2 val, dz, dzb;
    fpw_tps(x, base, n, paired, val, dz, dzb);
    float inv = 1.0 / (dot(dz, dz) - dot(dzb, dzb));
    fpw_node_a = fpw_conj(dz) * inv;
    fpw_node_b = -dzb * inv;
    bool ok = fpw_finite(x) && fpw_finite(fpw_node_a) && fpw_finite(fpw_node_b);
    fpw_node_x = ok ? x : vec2(fpw_nan());
    fpw_node_done = true;
}
#endif

// ---- one stage and the whole map -----------------------------------------
// _evaluate_stage: regions, pre-Möbius, core, post-Möbius. `core` and
// `n_regions` are arguments so that a program specialized to one kind of
// map can pass constants (the compiler then drops the other cores and
// reads the block at fixed offsets); the values still come from the block.
vec2 fpw_stage_of(vec2 z, int base, int core, int n_regions) {
    vec4 header = fpw_rows[base + FPW_ROW_HEADER];
    int n = int(header.y);
    int iters = int(header.w);
    bool newton = core == FPW_CORE_TPS_INVERSE || core == FPW_CORE_TPS_PAIRS_INVERSE;
#ifdef FPW_COARSE_PASS
    if (fpw_node_done) return z;
    if (newton) {
        fpw_node_x = fpw_node_a = fpw_node_b = vec2(fpw_nan());
        bool solve = !(base == 1 && fpw_node_unread(z, base, n_regions));
        for (int once = 0; once < 1 && solve; ++once) {
            fpw_coarse_node(z, base, n, core == FPW_CORE_TPS_PAIRS_INVERSE, iters);
        }
        fpw_node_done = true;
        return z;
    }
#endif
    bool seeded = false;
#ifdef FPW_COARSE
    seeded = newton && fpw_seed_pending;
    fpw_seed_pending = fpw_seed_pending && !newton;
#endif
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
#ifdef FPW_REGION_PASS
    // the region pass of a split draw (fpiwarp/backends/gl/band.py): the
    // seeded stage's other pixels are left to the full program's draw over
    // the band, so that this program holds none of the Newton code (llvmpipe
    // runs an if's body for every SIMD group, under a mask)
    if (seeded) return vec2(fpw_nan());
#endif
    vec4 scale = fpw_row(base + FPW_ROW_SCALE);  // k1, k2
    vec4 post = fpw_row(base + FPW_ROW_POST);    // s2, q2
    vec2 p = fpw_pre(z, base);
    if (core == FPW_CORE_AFFINE) {
        vec4 l12 = fpw_row(base + FPW_ROW_L12);
        vec2 l3 = fpw_row(base + FPW_ROW_L3).xy;
        p = fpw_cmul(l12.xy, p) + fpw_cmul(l12.zw, fpw_conj(p)) + l3;
    } else if (core == FPW_CORE_TPS || core == FPW_CORE_TPS_PAIRS) {
        vec2 dz, dzb;
        fpw_tps(p, base, n, core == FPW_CORE_TPS_PAIRS, p, dz, dzb);
    } else if (newton) {
        p = fpw_newton_seeded(p, base, n, core == FPW_CORE_TPS_PAIRS_INVERSE, iters, fpw_row(base + FPW_ROW_L3).z,
                              seeded);
    } else {
        return vec2(fpw_nan());  // a core this shader does not know: outside (the host refuses it first)
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
//   FPW_STAGE(base, core, n_regions)
// with constants, one per stage (the same evaluation, unrolled); each walk
// of the stages defines FPW_STAGE (here: z = fpw_stage_of(...); the
// Wirtinger walk of include/antialias.glsl: with the derivatives).
vec2 fpw_map(vec2 z) {
#ifdef FPW_STAGES
#define FPW_STAGE(base, core, n_regions) z = fpw_stage_of(z, base, core, n_regions);
    FPW_STAGES
#undef FPW_STAGE
#else
    int n_stages = int(fpw_rows[0].x);
    for (int k = 0; k < n_stages; ++k) {
        z = fpw_stage(z, 1 + k * FPW_STAGE_ROWS);
    }
#endif
    return z;
}
