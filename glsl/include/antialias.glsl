// Antialiasing from the analytic Jacobian (FPW_ANTIALIAS): the stage walk
// with Wirtinger derivatives and the footprint average over the source
// pyramid, mirroring fpiwarp/sampling/antialias.py, fpiwarp/sampling/pyramid.py
// and fpiwarp/block/jacobian.py. Part of
// fpiwarp.glsl (FPW_WITH_SAMPLER), after sample.glsl.

#ifdef FPW_ANTIALIAS
// ---- antialiasing (fpiwarp/_antialias.py, fpiwarp/block/jacobian.py) ------
// The block's Wirtinger derivatives chained stage after stage, and the
// average of nx × ny sub-samples of the pixel's footprint, the
// parallelogram spanned by the Jacobian's columns ex, ey.

// (g o f)_z, (g o f)_zbar from g's derivatives (gw, gwb) and f's (dz, dzb)
void fpw_chain(vec2 gw, vec2 gwb, inout vec2 dz, inout vec2 dzb) {
    vec2 a = fpw_cmul(gw, dz) + fpw_cmul(gwb, fpw_conj(dzb));
    dzb = fpw_cmul(gw, dzb) + fpw_cmul(gwb, fpw_conj(dz));
    dz = a;
}

// jacobian.stage_wirtinger: fpw_stage_of with its derivatives chained into
// dz, dzb (core and n_regions arguments as there: constants in a program
// specialized to a kind of map)
vec2 fpw_stage_wirtinger_of(vec2 z, int base, int core, int n_regions, inout vec2 dz, inout vec2 dzb) {
    vec4 header = fpw_rows[base + FPW_ROW_HEADER];
    int n = int(header.y);
    int iters = int(header.w);
    float best = 0.0;
    vec2 outside = vec2(fpw_nan());
    vec2 outside_dz = vec2(fpw_nan());
    for (int r = 0; r < n_regions; ++r) {
        vec4 on = fpw_rows[base + FPW_ROW_REGIONS + 2 * r];
        vec4 ab = fpw_rows[base + FPW_ROW_REGIONS + 2 * r + 1];
        float depth = fpw_cmul(z - on.xy, fpw_conj(on.zw)).x;
        if (depth > best) {
            best = depth;
            outside = fpw_cmul(ab.xy, z) + ab.zw;
            outside_dz = ab.xy;
        }
    }
    if (best > 0.0) {
        fpw_chain(outside_dz, vec2(0.0), dz, dzb);
        return outside;
    }
    vec4 pre = fpw_row(base + FPW_ROW_PRE);
    vec4 scale = fpw_row(base + FPW_ROW_SCALE);
    vec4 post = fpw_row(base + FPW_ROW_POST);
    vec2 u = z - pre.xy;
    vec2 den = vec2(1.0, 0.0) - fpw_cmul(pre.zw, u);
    vec2 p = fpw_cdiv(fpw_cmul(scale.xy, u), den);
    vec2 sdz = fpw_cdiv(scale.xy, fpw_cmul(den, den));
    vec2 sdzb = vec2(0.0);
    vec2 val, gz, gzb;
    if (core == FPW_CORE_AFFINE) {
        vec4 l12 = fpw_row(base + FPW_ROW_L12);
        p = fpw_cmul(l12.xy, p) + fpw_cmul(l12.zw, fpw_conj(p)) + fpw_row(base + FPW_ROW_L3).xy;
        fpw_chain(l12.xy, l12.zw, sdz, sdzb);
    } else if (core == FPW_CORE_TPS || core == FPW_CORE_TPS_PAIRS) {
        fpw_tps(p, base, n, core == FPW_CORE_TPS_PAIRS, val, gz, gzb);
        p = val;
        fpw_chain(gz, gzb, sdz, sdzb);
    } else if (core == FPW_CORE_TPS_INVERSE || core == FPW_CORE_TPS_PAIRS_INVERSE) {
        bool paired = core == FPW_CORE_TPS_PAIRS_INVERSE;
        p = fpw_newton(p, base, n, paired, iters, fpw_row(base + FPW_ROW_L3).z);
        fpw_tps(p, base, n, paired, val, gz, gzb);
        float det = dot(gz, gz) - dot(gzb, gzb);
        fpw_chain(fpw_conj(gz) / det, -gzb / det, sdz, sdzb);
    } else {
        dz = vec2(fpw_nan());
        dzb = vec2(fpw_nan());
        return vec2(fpw_nan());
    }
    vec2 den2 = vec2(1.0, 0.0) - fpw_cmul(post.xy, p);
    vec2 g = fpw_cdiv(scale.zw, fpw_cmul(den2, den2));
    fpw_chain(fpw_cmul(g, sdz), fpw_cmul(g, sdzb), dz, dzb);
    return post.zw + fpw_cdiv(fpw_cmul(scale.zw, p), den2);
}

// _antialias.tap_counts: 1 for len <= 1 + FPW_AA_SLACK or NaN, else
// ceil(min(len / SPACING, max(KNEE_TAPS, len / FAR_SPACING)) - SLACK) in
// 2..FPW_AA_MAX_TAPS
float fpw_aa_count(float len) {
    if (isnan(len) || len <= 1.0 + FPW_AA_SLACK) return 1.0;
    float n = min(len / FPW_AA_SPACING, max(float(FPW_AA_KNEE_TAPS), len / FPW_AA_FAR_SPACING));
    return clamp(ceil(n - FPW_AA_SLACK), 2.0, float(FPW_AA_MAX_TAPS));
}

// jacobian.wirtinger: the block map's derivatives f_z, f_zbar at xy, the
// stages walked as fpw_map walks them (FPW_STAGES: specialized, unrolled)
void fpw_map_wirtinger(vec2 xy, out vec2 dz, out vec2 dzb) {
    dz = vec2(1.0, 0.0);
    dzb = vec2(0.0);
    vec2 z = xy;
#ifdef FPW_STAGES
#define FPW_STAGE(base, core, n_regions) z = fpw_stage_wirtinger_of(z, base, core, n_regions, dz, dzb);
    FPW_STAGES
#undef FPW_STAGE
#else
    int n_stages = int(fpw_rows[0].x);
    for (int k = 0; k < n_stages; ++k) {
        int base = 1 + k * FPW_STAGE_ROWS;
        vec4 header = fpw_rows[base + FPW_ROW_HEADER];
        z = fpw_stage_wirtinger_of(z, base, int(header.x), int(header.z), dz, dzb);
    }
#endif
}

// the footprint's edges J (1, 0) and J (0, 1) (_antialias.footprint_edges)
vec2 fpw_edge_x(vec2 dz, vec2 dzb) { return dz + dzb; }
vec2 fpw_edge_y(vec2 dz, vec2 dzb) { return vec2(dzb.y - dz.y, dz.x - dzb.x); }

#ifdef FPW_HW_FILTER
// ---- the texture unit's own filter (FPW_HW_FILTER with FPW_ANTIALIAS) -----
// The option hardware_filter with antialias: pixels that do not shrink (both
// level-0 counts 1) are the plain option's, bit for bit; the others read
// the source's mipmaps (GL's own, floor sizes, built by the driver) by
// textureGrad with the footprint edges as gradients: trilinear
// minification, anisotropic where the driver offers it (the host sets the
// sampler). No box average and no pyramid of the reference: its accuracy is
// measured (benchmarks/antialias.py), not mirrored. A NaN edge counts as 0
// (the reference's magnifying NaN), an edge over FPW_HW_EDGE_LIMIT source
// pixels (next to the pole) as that long: the coarsest level.
#define FPW_HW_EDGE_LIMIT 65536.0
vec2 fpw_hw_edge(vec2 e, float len) {
    if (isnan(len)) return vec2(0.0);
    return len <= FPW_HW_EDGE_LIMIT ? e : vec2(FPW_HW_EDGE_LIMIT, 0.0);
}

vec4 fpw_sample_footprint(vec2 pos, vec2 ex, vec2 ey) {
    float lx = length(ex);
    float ly = length(ey);
    if (fpw_aa_count(lx) == 1.0 && fpw_aa_count(ly) == 1.0) return fpw_sample(pos);
    return fpw_hw_sample(pos, fpw_hw_edge(ex, lx), fpw_hw_edge(ey, ly));
}
#else
// ---- the pyramid (fpiwarp/sampling/pyramid.py) ------------------------------
// Levels k >= 1 of the source, float32, packed in one atlas texture built
// by the host (fpiwarp/backends/gl/pyramid.py): level k's texels are the
// atlas texels fpw_levels[k].xy + (col, row), of size fpw_levels[k].zw;
// fpw_aa_top is the coarsest level (0: no level >= 1). Level 0 is the
// source texture itself, sampled by fpw_sample. FPW_TILED: the atlas
// texture holds atlas texels fpw_pyramid_tile = [x0, x0 + w) × [y0, y0 + h)
// only, like the source's tiles (other texels contribute nothing).
uniform sampler2D fpw_pyramid;
uniform ivec4 fpw_levels[FPW_AA_MAX_LEVEL + 1];
uniform int fpw_aa_top;
#ifdef FPW_TILED
uniform ivec4 fpw_pyramid_tile;
#endif

// A texel of the level at atlas rectangle `level` (fpw_texel's rules).
vec4 fpw_level_texel(ivec4 level, int col, int row, bool inside) {
    if (FPW_MODE == FPW_MODE_CONSTANT && !inside) return fpw_cval_term();
    ivec2 ij = level.xy + ivec2(col, row);
#ifdef FPW_TILED
    ij -= fpw_pyramid_tile.xy;
    if (any(lessThan(ij, ivec2(0))) || any(greaterThanEqual(ij, fpw_pyramid_tile.zw))) return vec4(0.0);
#endif
    return texelFetch(fpw_pyramid, ij, 0);
}

// Pyramid.sample for k >= 1: the level (atlas rectangle `level`, 2^k =
// `scale`) bilinearly at level coordinate (pos + 0.5) / 2^k - 0.5, border
// modes on the level's own size (fpw_sample's order-1 sum).
vec4 fpw_sample_level(ivec4 level, float scale, vec2 pos) {
    vec2 lp = (pos + 0.5) / scale - 0.5;
    if (!fpw_in_range(lp)) return fpw_cval_term();
    lp = clamp(lp, vec2(-FPW_COORD_LIMIT), vec2(FPW_COORD_LIMIT));
    vec2 base = floor(lp);
    vec2 t = lp - base;
    ivec2 i = ivec2(base);
    float wx[2] = float[2](1.0 - t.x, t.x);
    float wy[2] = float[2](1.0 - t.y, t.y);
    int cols[2] = int[2](fpw_border(i.x, level.z), fpw_border(i.x + 1, level.z));
    bool cols_in[2] = bool[2](i.x >= 0 && i.x < level.z, i.x + 1 >= 0 && i.x + 1 < level.z);
    vec4 out_ = vec4(0.0);
    for (int r = 0; r < 2; ++r) {
        int j = i.y + r;
        int row = fpw_border(j, level.w);
        bool row_in = j >= 0 && j < level.w;
        for (int k = 0; k < 2; ++k) {
            out_ += (wy[r] * wx[k]) * fpw_level_texel(level, cols[k], row, row_in && cols_in[k]);
        }
    }
    return out_;
}

// antialias.supersample at level k: the box average of the footprint at
// pos with edges ex, ey, sub-sample counts from the edges in level-k texels
vec4 fpw_supersample(int k, vec2 pos, vec2 ex, vec2 ey) {
    float scale = exp2(float(k));
    float nx = fpw_aa_count(length(ex) / scale);
    float ny = fpw_aa_count(length(ey) / scale);
    ivec4 level = fpw_levels[k];
    vec4 acc = vec4(0.0);
    for (int j = 0; j < int(ny); ++j) {
        float t = (2.0 * float(j) + 1.0 - ny) / (2.0 * ny);
        for (int i = 0; i < int(nx); ++i) {
            float s = (2.0 * float(i) + 1.0 - nx) / (2.0 * nx);
            vec2 p = pos + (ex * s + ey * t);
            acc += k == 0 ? fpw_sample(p) : fpw_sample_level(level, scale, p);
        }
    }
    return acc / (nx * ny);
}

// antialias.sample_antialiased at source position pos with footprint
// edges ex, ey (source pixels): plain where both level-0 counts are 1;
// else the pole rule, then level k = floor(lod) of pyramid_levels,
// blended into level k + 1 with weight u in the last FPW_AA_BLEND of the
// octave.
vec4 fpw_sample_footprint(vec2 pos, vec2 ex, vec2 ey) {
    float lx = length(ex);
    float ly = length(ey);
    if (fpw_aa_count(lx) == 1.0 && fpw_aa_count(ly) == 1.0) return fpw_sample(pos);
    if (!fpw_in_range(pos)) return fpw_cval_term();
    float short_ = isnan(lx) || isnan(ly) ? 0.0 : min(lx, ly);
    float top = float(fpw_aa_top);
    float lod = clamp(log2(max(short_ * (1.0 + FPW_AA_SLACK) / FPW_AA_LEVEL_SPAN, 1.0)), 0.0, top);
    float kf = floor(lod);
    float u = kf >= top ? 0.0 : clamp((lod - kf - 1.0 + FPW_AA_BLEND) / FPW_AA_BLEND, 0.0, 1.0);
    int k = int(kf);
    vec4 v = (1.0 - u) * fpw_supersample(k, pos, ex, ey);
    if (u > 0.0) v += u * fpw_supersample(k + 1, pos, ex, ey);
    return v;
}
#endif  // FPW_HW_FILTER

// _antialias.sample_antialiased at output position xy
vec4 fpw_sample_antialiased(vec2 xy) {
    vec2 pos = fpw_map(xy);  // exactly the plain warp's position
    vec2 dz, dzb;
    fpw_map_wirtinger(xy, dz, dzb);
    return fpw_sample_footprint(pos, fpw_edge_x(dz, dzb), fpw_edge_y(dz, dzb));
}
#endif  // FPW_ANTIALIAS
