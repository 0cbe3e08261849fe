/* fpiwarp.cl: the OpenCL kernels of fpiwarp's "opencl" backend.
 *
 * All math lives in fpiwarp_map.h (mirroring fpiwarp/block/reference.py
 * and fpiwarp/_sampling.py); the host prepends the block contract's
 * #defines (fpiwarp/block/codegen.py). The parameter block is a __constant float4
 * buffer; its values never change the program. A program is built once
 * per kind of map (FW_KIND_k defines, optional) and, for warp_image, kind
 * of sampling (FW_T, FW_C, FW_INT, FW_TOP, FW_ORDER, FW_MODE, FW_VN): see
 * the header. Points, and the map of each pixel, are computed in scalars,
 * so that CPU drivers vectorize them across work-items; the sampling is
 * written in vector types of FW_VN lanes instead (see the header for why).
 */
#include "fpiwarp_map.h"

/* FW_POINT: the element type of map_points' input and output, double
 * where the device has fp64 (no conversion passes on the host), else float.
 * The math is float32 either way. */
#ifndef FW_POINT
#define FW_POINT float
#endif
#if FW_POINT_DOUBLE
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#endif

/* FW_BATCH (fpiwarp/backends/opencl_batch.py): one launch warps (or maps
 * the points of) many images, launch dimension 2 naming which. Item z of
 * the launch reads block z of the stacked blocks (block_rows float4 rows
 * each; 0 shares one block) and item which[z] of the stacked inputs and
 * outputs (in_items, out_items values apart). Everything else is the
 * single kernel's code, so a batch equals the loop bit for bit.
 *
 * z is the group's id, not the item's: every batch kernel's groups are one
 * item deep (reqd_work_group_size(..., 1)), so the two are equal. Selected
 * by get_global_id(2), PoCL 3.1 compiled part of the per-pixel code 4
 * lanes wide instead of 8 (186 packed 128-bit float instructions against
 * the single kernel's 26; likely it did not see the selected pointers as
 * uniform over the group) and the same warps took 1.2x the single
 * kernel's CPU time (benchmarks/results/cpu_profile.md). */
#ifdef FW_BATCH
#define FW_BATCH_ARGS , __global const int *restrict which, int block_rows
#define FW_BATCH_SELECT(fw_in, fw_out, in_items, out_items) \
    do {                                                    \
        size_t fw_z = get_group_id(2), fw_n = which[fw_z];  \
        block += fw_z * block_rows;                         \
        fw_in += fw_n * (size_t)(in_items);                 \
        fw_out += fw_n * (size_t)(out_items);               \
    } while (0)
#else
#define FW_BATCH_ARGS
#define FW_BATCH_SELECT(fw_in, fw_out, in_items, out_items)
#endif

/* out[i] = map(pts[i]) for i < n; points are interleaved (x, y).
 *
 * Work-groups of FW_LOCAL_X points (the host rounds the global size up),
 * in phases split by barriers: read the group's points into local arrays
 * of x and of y, map them, write them back. The map phase is one point
 * per work-item: on a CPU, PoCL makes it a loop over work-items and
 * vectorizes it.
 *
 * FW_POINT_VN 8 (CPUs): the first FW_LOCAL_X / 8 work-items read and write
 * 8 points each as vectors, split into x and y (and joined back) by
 * even/odd shuffles; a work-item at the end of the points does
 * them one by one, and none writes past the last point. Otherwise (GPUs)
 * each work-item reads and writes its own point, x then y in phases of
 * their own (padding work-items redo the last point, writing the same
 * value): on a CPU a two-lane (x, y) access in one phase would stop
 * PoCL's vectorizer. */
#ifndef FW_POINT_VN
#define FW_POINT_VN 1
#endif
#if FW_POINT_VN == 8
/* 4-element vectors of points (two points each): 256 bits at most, the
 * widest that builtins take by value without AVX-512 */
#define FW_TO_POINT4 FW_PASTE(convert_, FW_PASTE(FW_POINT, 4))
#endif
__kernel __attribute__((reqd_work_group_size(FW_LOCAL_X, 1, 1)))
void map_points(fw_block_t block, __global const FW_POINT *restrict pts,
                __global FW_POINT *restrict out, int n FW_BATCH_ARGS)
{
    FW_BATCH_SELECT(pts, out, 2 * n, 2 * n);
    __local float px[FW_LOCAL_X], py[FW_LOCAL_X];
    int i = get_global_id(0), l = get_local_id(0);
#if FW_POINT_VN == 8
    int first = get_group_id(0) * FW_LOCAL_X + 8 * l; /* the work-item's first point, in the I/O phases */
    bool io = l < FW_LOCAL_X / 8, whole = first + 8 <= n;
    if (io && whole) {
        __global const FW_POINT *p = pts + 2 * first;
        float8 lo = (float8)(convert_float4(vload4(0, p)), convert_float4(vload4(1, p)));
        float8 hi = (float8)(convert_float4(vload4(2, p)), convert_float4(vload4(3, p)));
        vstore8((float8)(lo.even, hi.even), l, px);
        vstore8((float8)(lo.odd, hi.odd), l, py);
    } else if (io) {
        for (int k = 0; k < 8; ++k) {
            int at = min(first + k, n - 1);
            px[8 * l + k] = (float)pts[2 * at];
            py[8 * l + k] = (float)pts[2 * at + 1];
        }
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    fw_c w = fw_map(block, fw_cx(px[l], py[l]));
    px[l] = w.re;
    py[l] = w.im;
    barrier(CLK_LOCAL_MEM_FENCE);
    if (io && whole) {
        float8 x = vload8(l, px), y = vload8(l, py);
        float8 lo = shuffle2(x, y, (uint8)(0, 8, 1, 9, 2, 10, 3, 11));
        float8 hi = shuffle2(x, y, (uint8)(4, 12, 5, 13, 6, 14, 7, 15));
        __global FW_POINT *p = out + 2 * first;
        vstore4(FW_TO_POINT4(lo.lo), 0, p);
        vstore4(FW_TO_POINT4(lo.hi), 1, p);
        vstore4(FW_TO_POINT4(hi.lo), 2, p);
        vstore4(FW_TO_POINT4(hi.hi), 3, p);
    } else if (io) {
        for (int k = 0; k < 8 && first + k < n; ++k) {
            out[2 * (first + k)] = px[8 * l + k];
            out[2 * (first + k) + 1] = py[8 * l + k];
        }
    }
#else
    int at = min(i, n - 1); /* padding work-items repeat the last point */
    px[l] = (float)pts[2 * at];
    barrier(CLK_LOCAL_MEM_FENCE);
    py[l] = (float)pts[2 * at + 1];
    barrier(CLK_LOCAL_MEM_FENCE);
    fw_c w = fw_map(block, fw_cx(px[l], py[l]));
    px[l] = w.re;
    py[l] = w.im;
    barrier(CLK_LOCAL_MEM_FENCE);
    out[2 * at] = px[l];
    barrier(CLK_LOCAL_MEM_FENCE);
    out[2 * at + 1] = py[l];
#endif
}

#ifdef FW_T
/* The store phase of every warp kernel: the FW_VN pixels of the kernel's
 * sampled value v (fw_pxv), converted to the image's type, into row oy
 * from the work-item's first pixel gx0 + FW_VN * l. A work-item whose
 * pixels all lie in the row stores at constant offsets from one address;
 * one at the row's end clamps each lane (padding lanes rewrite the row's
 * last pixel). */
#define FW_RESULT(k, _) fw_ov res##k = FW_TO_DTYPE(v.c##k);
#define FW_STORE_C(k, lane) dst[at + k] = (FW_T)FW_LANE(res##k, lane);
#define FW_STORE_LANE(lane, _)                                         \
    {                                                                  \
        int at = (oy * ow + min(gx0 + FW_VN * l + lane, ow - 1)) * FW_C; \
        FW_EACH_C(FW_STORE_C, lane)                                    \
    }
#define FW_STORE_C_AT(k, lane) out[FW_C * lane + k] = (FW_T)FW_LANE(res##k, lane);
#define FW_STORE_LANE_AT(lane, _) FW_EACH_C(FW_STORE_C_AT, lane)
#define FW_STORE_PIXELS()                                                 \
    do {                                                                  \
        FW_EACH_C(FW_RESULT, _)                                           \
        if (gx0 + FW_VN * (l + 1) <= ow) {                                \
            __global FW_T *out = dst + (oy * ow + gx0 + FW_VN * l) * FW_C; \
            FW_EACH_LANE(FW_STORE_LANE_AT, _)                             \
        } else {                                                          \
            FW_EACH_LANE(FW_STORE_LANE, _)                                \
        }                                                                 \
    } while (0)

/* dst (oh x ow x FW_C) = src (h x w x FW_C) sampled at map(x, y) for every
 * output pixel center (x, y); block holds the inverse of the user's map.
 *
 * Work-groups are tiles of FW_LOCAL_X x FW_LOCAL_Y pixels (the host
 * rounds the global size up; padding work-items past a row's end redo the
 * row's last pixel, writing the same values; padding rows past the last
 * map the last row and write nothing). Tiles several rows high (on CPUs)
 * keep the source rows they read in the cache: consecutive rows read
 * overlapping source rows. Two phases split by a barrier: the map, one
 * pixel per work-item, into local memory (on a CPU, PoCL compiles it into
 * a loop over work-items and vectorizes it); then the sampling, FW_VN
 * pixels per work-item in vector types, by the first FW_LOCAL_X / FW_VN
 * work-items of each row. */
/* FW_COARSE (a map with a Newton core, fpiwarp/block/coarse.py): warp_image
 * takes the coarse pass's records (coarse_pass below, nx x ny nodes), and
 * its map phase is fw_map_coarse_group's phases, which check each pixel's
 * seed from them and solve where the check fails. A batch (FW_BATCH) holds the records
 * of each item of the launch, item z's from node z nx ny on
 * (FW_COARSE_SELECT). */
#ifdef FW_COARSE
#define FW_COARSE_ARGS , __global const float *restrict coarse, int nx, int ny
#else
#define FW_COARSE_ARGS
#endif
#if defined(FW_COARSE) && defined(FW_BATCH)
#define FW_COARSE_SELECT() (coarse += get_group_id(2) * (size_t)(FW_COARSE_FLOATS * nx * ny))
#else
#define FW_COARSE_SELECT()
#endif

__kernel __attribute__((reqd_work_group_size(FW_LOCAL_X, FW_LOCAL_Y, 1)))
void warp_image(fw_block_t block, __global const FW_T *restrict src, int w, int h,
                __global FW_T *restrict dst, int ow, int oh, float4 cval FW_COARSE_ARGS FW_BATCH_ARGS)
{
    FW_BATCH_SELECT(src, dst, w * h * FW_C, ow * oh * FW_C);
    FW_COARSE_SELECT();
    __local float pos_x[FW_LOCAL_Y * FW_LOCAL_X], pos_y[FW_LOCAL_Y * FW_LOCAL_X];
    int l = get_local_id(0), oy = get_global_id(1);
    int gx0 = get_group_id(0) * FW_LOCAL_X; /* the group's first pixel */
    int row = get_local_id(1) * FW_LOCAL_X; /* the row's part of the local arrays */
#ifdef FW_COARSE
    __local fw_coarse_group_t group;
    fw_map_coarse_group(block, coarse, nx, ny, row + l, min(gx0 + l, ow - 1), min(oy, oh - 1), gx0,
                        get_group_id(1) * FW_LOCAL_Y, ow, oh, &group, pos_x, pos_y);
#else
    fw_c s = fw_map(block, fw_cx((float)min(gx0 + l, ow - 1), (float)min(oy, oh - 1)));
    pos_x[row + l] = s.re;
    pos_y[row + l] = s.im;
#endif
    barrier(CLK_LOCAL_MEM_FENCE);
    if (l >= FW_LOCAL_X / FW_VN || oy >= oh)
        return;
    fw_fv sx = FW_VLOAD(pos_x + row + FW_VN * l), sy = FW_VLOAD(pos_y + row + FW_VN * l);
    fw_pxv v = fw_sample(src, w, h, sx, sy, cval);
    FW_STORE_PIXELS();
}
#endif

#ifdef FW_COARSE
/* The coarse pass: node (i, j)'s record (fw_coarse_node at output position
 * (FW_COARSE_STEP i, FW_COARSE_STEP j)) into coarse, FW_COARSE_FLOATS
 * floats a node, nodes row by row; padding work-items redo the last node.
 * A batch (FW_BATCH): item z of launch dimension 2 solves block z's nodes
 * into its part of coarse (as warp_image reads them). */
__kernel __attribute__((reqd_work_group_size(FW_LOCAL_X, 1, 1)))
void coarse_pass(fw_block_t block, __global float *restrict coarse, int nx, int ny FW_BATCH_ARGS)
{
#ifdef FW_BATCH
    block += get_group_id(2) * block_rows; /* groups are one item deep, as FW_BATCH_SELECT's */
#endif
    FW_COARSE_SELECT();
    int k = min((int)get_global_id(0), nx * ny - 1);
    int i = k % nx, j = k / nx;
    fw_seed_t rec = fw_coarse_node(block, fw_cx((float)(FW_COARSE_STEP * i), (float)(FW_COARSE_STEP * j)));
    __global float *r = coarse + FW_COARSE_FLOATS * k;
    r[0] = rec.x.re;
    r[1] = rec.x.im;
    r[2] = rec.a.re;
    r[3] = rec.a.im;
    r[4] = rec.b.re;
    r[5] = rec.b.im;
}
#endif

#if defined(FW_T) && defined(FW_AA)
/* _antialias.tap_counts: sub-samples along a footprint edge of length
 * len (source pixels), as a float: 1 for len <= 1 + FW_AA_SLACK or NaN,
 * else ceil(min(len / SPACING, max(KNEE_TAPS, len / FAR_SPACING)) - SLACK)
 * in 2..FW_AA_MAX_TAPS */
FW_FN fw_fv fw_aa_count(fw_fv len)
{
    fw_fv n = fmin(len / FW_AA_SPACING, fmax((fw_fv)(float)FW_AA_KNEE_TAPS, len / FW_AA_FAR_SPACING));
    n = clamp(ceil(n - FW_AA_SLACK), 2.0f, (float)FW_AA_MAX_TAPS);
    return select(n, (fw_fv)1.0f, isnan(len) | (len <= 1.0f + FW_AA_SLACK));
}

/* the largest lane of v (at least 1) */
FW_FN float fw_aa_lanes_max(fw_fv v)
{
    float m = 1.0f;
#define FW_AA_MAX_LANE(k, _) m = max(m, FW_LANE(v, k));
    FW_EACH_LANE(FW_AA_MAX_LANE, _)
#undef FW_AA_MAX_LANE
    return m;
}

/* the smallest lane of v */
FW_FN float fw_aa_lanes_min(fw_fv v)
{
    float m = FW_LANE(v, 0);
#define FW_AA_MIN_LANE(k, _) m = min(m, FW_LANE(v, k));
    FW_EACH_LANE(FW_AA_MIN_LANE, _)
#undef FW_AA_MIN_LANE
    return m;
}

/* ---- the source pyramid (fpiwarp/sampling/pyramid.py) ------------------ */
/* Level k >= 1 of a source (h x w x FW_C), float32, texel (i, j) the mean of
 * level k - 1's 2 x 2 texels (2i, 2j) .. (2i + 1, 2j + 1), an index past the
 * last row or column clamped to it; sums in the reference's order
 * 0.25 ((a + b) + (c + d)). One work-item per texel of the new level (ow x
 * oh, from element dst_at of dst), launch dimension 2 the image of a stack
 * (src_items, dst_items elements apart). pyramid_first halves the source
 * in its own type, pyramid_next the float32 level from element src_at of
 * the pyramid (the same buffer as dst: the two levels do not overlap). */
#define FW_HALVE_C(k, _) \
    dst[at + k] = 0.25f * (((float)src[r0 + c0 + k] + (float)src[r0 + c1 + k]) + \
                           ((float)src[r1 + c0 + k] + (float)src[r1 + c1 + k]));
#define FW_HALVE_BODY                                                       \
    int i = get_global_id(0), j = get_global_id(1);                         \
    if (i >= ow || j >= oh)                                                 \
        return;                                                             \
    src += src_at + get_global_id(2) * (size_t)src_items;                   \
    dst += dst_at + get_global_id(2) * (size_t)dst_items;                   \
    int c0 = 2 * i * FW_C, c1 = min(2 * i + 1, w - 1) * FW_C;               \
    int r0 = 2 * j * (w * FW_C), r1 = min(2 * j + 1, h - 1) * (w * FW_C);   \
    int at = (j * ow + i) * FW_C;                                           \
    FW_EACH_C(FW_HALVE_C, _)
__kernel void pyramid_first(__global const FW_T *restrict src, int src_at, int w, int h,
                            __global float *restrict dst, int dst_at, int ow, int oh, int src_items, int dst_items)
{
    FW_HALVE_BODY
}
__kernel void pyramid_next(__global const float *src, int src_at, int w, int h, __global float *dst, int dst_at,
                           int ow, int oh, int src_items, int dst_items)
{
    FW_HALVE_BODY
}
#undef FW_HALVE_BODY
#undef FW_HALVE_C

/* sampler.sample of a float32 level (lw x lh x FW_C) with order 1 at FW_VN
 * level coordinates (fx, fy): bilinear, FW_MODE on the level's own indices
 * and size, cval outside in constant mode and where not finite; the
 * interior path where all lanes' taps lie inside, as fw_sample's. */
#define FW_LV_VALUE(k, at) FW_GATHER(fw_fv, FW_LV_AT_##k)
#define FW_LV_AT_0(j) lvl[FW_LANE(at, j) + (off + 0)]
#define FW_LV_AT_1(j) lvl[FW_LANE(at, j) + (off + 1)]
#define FW_LV_AT_2(j) lvl[FW_LANE(at, j) + (off + 2)]
#define FW_LV_AT_3(j) lvl[FW_LANE(at, j) + (off + 3)]
#if FW_MODE == FW_MODE_CONSTANT
#define FW_LV_CHANNEL(k, _) acc##k += wgt * select((fw_fv)(cval.s##k), FW_LV_VALUE(k, at), in);
#else
#define FW_LV_CHANNEL(k, _) acc##k += wgt * FW_LV_VALUE(k, at);
#endif
#define FW_LV_INDEX(i)                                \
    fw_iv col##i = fw_border(x##i, lw) * FW_C;        \
    fw_iv col_in##i = fw_inside(x##i, lw);            \
    fw_iv row##i = fw_border(y##i, lh) * (lw * FW_C); \
    fw_iv row_in##i = fw_inside(y##i, lh);
#define FW_LV_TAP(i, j)                              \
    {                                                \
        fw_fv wgt = y##w##j * x##w##i;               \
        fw_iv at = row##j + col##i;                  \
        fw_iv in = row_in##j & col_in##i;            \
        const int off = 0;                           \
        FW_EACH_C(FW_LV_CHANNEL, _)                  \
    }
#define FW_LV_TAP_IN(i, j)                           \
    {                                                \
        fw_fv wgt = y##w##j * x##w##i;               \
        const int off = i * FW_C;                    \
        FW_EACH_C(FW_LV_CHANNEL_IN, _)               \
    }
#define FW_LV_CHANNEL_IN(k, _) acc##k += wgt * FW_LV_VALUE(k, at);
#define FW_LV_ROW_IN(j)                              \
    {                                                \
        fw_iv at = at0 + j * (lw * FW_C);            \
        FW_LV_TAP_IN(0, j) FW_LV_TAP_IN(1, j)        \
    }
FW_FN fw_pxv fw_sample_level(__global const float *lvl, int lw, int lh, fw_fv fx, fw_fv fy, float4 cval)
{
    fw_iv finite = (fabs(fx) <= FW_COORD_LIMIT) & (fabs(fy) <= FW_COORD_LIMIT);
    fw_fv x = select((fw_fv)0.0f, fx, finite);
    fw_fv y = select((fw_fv)0.0f, fy, finite);
    fw_iv x0 = fw_floor(x), y0 = fw_floor(y), x1 = x0 + 1, y1 = y0 + 1;
    fw_fv xw1 = x - FW_CONVERT(float, x0), yw1 = y - FW_CONVERT(float, y0);
    fw_fv xw0 = 1.0f - xw1, yw0 = 1.0f - yw1;
    fw_fv acc0 = 0.0f, acc1 = 0.0f, acc2 = 0.0f, acc3 = 0.0f;
    if (FW_ALL(finite & (x0 >= 0) & (x1 < lw) & (y0 >= 0) & (y1 < lh))) {
        fw_iv at0 = y0 * (lw * FW_C) + x0 * FW_C;
        FW_LV_ROW_IN(0)
        FW_LV_ROW_IN(1)
        fw_pxv out = {acc0, acc1, acc2, acc3};
        return out;
    }
    FW_LV_INDEX(0)
    FW_LV_INDEX(1)
    FW_LV_TAP(0, 0) FW_LV_TAP(1, 0)
    FW_LV_TAP(0, 1) FW_LV_TAP(1, 1)
    fw_pxv out = {select((fw_fv)cval.s0, acc0, finite), select((fw_fv)cval.s1, acc1, finite),
                  select((fw_fv)cval.s2, acc2, finite), select((fw_fv)cval.s3, acc3, finite)};
    return out;
}

/* warp_image with antialiasing (fpiwarp/sampling/antialias.py,
 * sample_antialiased): each pixel whose footprint shrinks (a level-0 count
 * above 1) the box average of its footprint, the parallelogram spanned by
 * the inverse map's Jacobian columns ex, ey at the pixel, supersampled at
 * pyramid level k (pyramid_levels: from the shorter edge) with the counts
 * of the edges in level-k texels (fw_aa_count), blended into level k + 1
 * with weight u in the last FW_AA_BLEND of an octave; other pixels the
 * plain sample, bit for bit. Level 0 is the source (the call's order and
 * type, fw_sample), levels >= 1 the float32 levels in `pyr` (levels[k] =
 * (first element, width, height) of level k), sampled bilinearly.
 * `built` levels are in pyr (top, the coarsest level of the source, clamps
 * the lod): a pixel needing a level past `built` reads level `built`
 * instead and sets *need (the host then builds them all and runs again).
 *
 * Same work-groups and phases as warp_image: the map and its derivatives
 * per pixel into local memory, then the sampling, FW_VN pixels per
 * work-item, for each level any lane reads, looping over the largest
 * counts of the lanes reading it (lanes with fewer sub-samples skip the
 * extra ones). The plain sample is taken only where some lane needs it. */
#ifdef FW_BATCH
#define FW_PYR_SELECT() (pyr += which[get_group_id(2)] * (size_t)pyr_items)
#else
#define FW_PYR_SELECT()
#endif
__kernel __attribute__((reqd_work_group_size(FW_LOCAL_X, FW_LOCAL_Y, 1)))
void warp_image_aa(fw_block_t block, __global const FW_T *restrict src, int w, int h,
                   __global FW_T *restrict dst, int ow, int oh, float4 cval,
                   __global const float *restrict pyr, __constant const int4 *levels, int top, int built,
                   int pyr_items, __global int *need FW_BATCH_ARGS)
{
    FW_PYR_SELECT();
    FW_BATCH_SELECT(src, dst, w * h * FW_C, ow * oh * FW_C);
    __local float pos_x[FW_LOCAL_Y * FW_LOCAL_X], pos_y[FW_LOCAL_Y * FW_LOCAL_X];
    __local float exx[FW_LOCAL_Y * FW_LOCAL_X], exy[FW_LOCAL_Y * FW_LOCAL_X];
    __local float eyx[FW_LOCAL_Y * FW_LOCAL_X], eyy[FW_LOCAL_Y * FW_LOCAL_X];
    int l = get_local_id(0), oy = get_global_id(1);
    int gx0 = get_group_id(0) * FW_LOCAL_X; /* the group's first pixel */
    int row = get_local_id(1) * FW_LOCAL_X; /* the row's part of the local arrays */
    /* the position exactly as warp_image computes it (so that a magnified
     * pixel is bit for bit the plain one: fw_map_wirtinger's value is
     * fw_map's, the same operations), the derivatives beside it */
    fw_c dz, dzb;
    fw_c s = fw_map_wirtinger(block, fw_cx((float)min(gx0 + l, ow - 1), (float)min(oy, oh - 1)), &dz, &dzb);
    pos_x[row + l] = s.re;
    pos_y[row + l] = s.im;
    /* ex = f_z + f_zbar, ey = i (f_z - f_zbar): the Jacobian's columns */
    exx[row + l] = dz.re + dzb.re;
    exy[row + l] = dz.im + dzb.im;
    eyx[row + l] = dzb.im - dz.im;
    eyy[row + l] = dz.re - dzb.re;
    barrier(CLK_LOCAL_MEM_FENCE);
    /* work-items whose pixels all lie past the row's end (padding) write
     * nothing: their sub-samples would only redo the row's last pixel */
    if (l >= FW_LOCAL_X / FW_VN || gx0 + FW_VN * l >= ow || oy >= oh)
        return;
    int at0 = row + FW_VN * l;
    fw_fv sx = FW_VLOAD(pos_x + at0), sy = FW_VLOAD(pos_y + at0);
    fw_fv ax = FW_VLOAD(exx + at0), ay = FW_VLOAD(exy + at0);
    fw_fv bx = FW_VLOAD(eyx + at0), by = FW_VLOAD(eyy + at0);
    fw_fv lx = sqrt(ax * ax + ay * ay), ly = sqrt(bx * bx + by * by);
    fw_fv nx0 = fw_aa_count(lx), ny0 = fw_aa_count(ly);
    fw_iv multi = (nx0 > 1.0f) | (ny0 > 1.0f);
    fw_pxv v = {0.0f, 0.0f, 0.0f, 0.0f};
    if (!FW_ALL(multi))
        v = fw_sample(src, w, h, sx, sy, cval);
    if (FW_ANY(multi)) {
        /* pyramid_levels: lod from the shorter edge (NaN: 0), its floor k,
         * the next level's weight u */
        fw_fv short_len = fmin(lx, ly);
        short_len = select(short_len, (fw_fv)0.0f, isnan(short_len));
        fw_fv lod = log2(fmax(short_len * ((1.0f + FW_AA_SLACK) / FW_AA_LEVEL_SPAN), 1.0f));
        lod = clamp(lod, 0.0f, (float)top);
        fw_fv k = FW_CONVERT(float, fw_floor(lod));
        fw_fv u = clamp((lod - k - 1.0f + FW_AA_BLEND) / FW_AA_BLEND, 0.0f, 1.0f);
        u = select(u, (fw_fv)0.0f, k >= (float)top);
        /* the levels any shrinking lane reads */
        fw_fv last = k + select((fw_fv)0.0f, (fw_fv)1.0f, u > 0.0f);
        fw_iv past = multi & (last > (float)built);
        if (FW_ANY(past))
            *need = 1;
        float lo = fw_aa_lanes_min(select((fw_fv)(float)FW_AA_MAX_LEVEL, k, multi));
        float hi = fw_aa_lanes_max(select((fw_fv)0.0f, last, multi));
        hi = min(hi, (float)built);
        fw_fv acc0 = 0.0f, acc1 = 0.0f, acc2 = 0.0f, acc3 = 0.0f;
        for (float lv = lo; lv <= hi; lv += 1.0f) {
            /* this level's weight in each lane: 1 - u at k, u at k + 1 */
            fw_fv wl = select((fw_fv)0.0f, 1.0f - u, k == lv) + select((fw_fv)0.0f, u, k + 1.0f == lv);
            wl = select((fw_fv)0.0f, wl, multi);
            fw_iv reads = wl > 0.0f;
            if (!FW_ANY(reads))
                continue;
            int ilv = (int)lv;
            float inv_scale = 1.0f / (float)(1 << ilv);
            fw_fv nx = fw_aa_count(lx * inv_scale), ny = fw_aa_count(ly * inv_scale);
            float mx = fw_aa_lanes_max(select((fw_fv)1.0f, nx, reads));
            float my = fw_aa_lanes_max(select((fw_fv)1.0f, ny, reads));
            int4 lvinfo = levels[ilv];
            __global const float *lvl = pyr + lvinfo.x;
            fw_fv sum0 = 0.0f, sum1 = 0.0f, sum2 = 0.0f, sum3 = 0.0f;
            fw_fv rx = 1.0f / (2.0f * nx), ry = 1.0f / (2.0f * ny);
            for (float j = 0.0f; j < my; j += 1.0f) {
                fw_fv t = (2.0f * j + 1.0f - ny) * ry;
                for (float i = 0.0f; i < mx; i += 1.0f) {
                    fw_fv sub = (2.0f * i + 1.0f - nx) * rx;
                    fw_iv live = ((fw_fv)i < nx) & ((fw_fv)j < ny);
                    fw_fv px = sx + (ax * sub + bx * t), py = sy + (ay * sub + by * t);
                    fw_pxv q;
                    if (ilv == 0)
                        q = fw_sample(src, w, h, px, py, cval);
                    else
                        q = fw_sample_level(lvl, lvinfo.y, lvinfo.z, (px + 0.5f) * inv_scale - 0.5f,
                                            (py + 0.5f) * inv_scale - 0.5f, cval);
#define FW_AA_ADD(k, _) sum##k += select((fw_fv)0.0f, q.c##k, live);
                    FW_EACH_C(FW_AA_ADD, _)
#undef FW_AA_ADD
                }
            }
            fw_fv part = wl / (nx * ny);
#define FW_AA_LEVEL(k, _) acc##k += select((fw_fv)0.0f, part * sum##k, reads);
            FW_EACH_C(FW_AA_LEVEL, _)
#undef FW_AA_LEVEL
        }
        fw_iv finite = (fabs(sx) <= FW_COORD_LIMIT) & (fabs(sy) <= FW_COORD_LIMIT);
#define FW_AA_PICK(k, _) v.c##k = select(v.c##k, select((fw_fv)cval.s##k, acc##k, finite), multi);
        FW_EACH_C(FW_AA_PICK, _)
#undef FW_AA_PICK
    }
    FW_STORE_PIXELS();
}
#endif
