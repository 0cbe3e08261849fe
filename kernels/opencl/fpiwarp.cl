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

#ifndef FW_LOCAL_X
#define FW_LOCAL_X 64
#endif
/* warp_image's work-groups are FW_LOCAL_X x FW_LOCAL_Y pixels */
#ifndef FW_LOCAL_Y
#define FW_LOCAL_Y 1
#endif

/* FW_BATCH (fpiwarp/backends/opencl_batch.py): one launch warps (or maps
 * the points of) many images, launch dimension 2 naming which. Item z of
 * the launch reads block z of the stacked blocks (block_rows float4 rows
 * each; 0 shares one block) and item which[z] of the stacked inputs and
 * outputs (in_items, out_items values apart). Everything else is the
 * single kernel's code, so a batch equals the loop bit for bit. */
#ifdef FW_BATCH
#define FW_BATCH_ARGS , __global const int *restrict which, int block_rows
#define FW_BATCH_SELECT(fw_in, fw_out, in_items, out_items) \
    do {                                                    \
        size_t fw_z = get_global_id(2), fw_n = which[fw_z]; \
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
#define FW_POINT_CAT2(a, b) a##b
#define FW_POINT_CAT(a, b) FW_POINT_CAT2(a, b)
#define FW_TO_POINT4 FW_POINT_CAT(convert_, FW_POINT_CAT(FW_POINT, 4))
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
__kernel __attribute__((reqd_work_group_size(FW_LOCAL_X, FW_LOCAL_Y, 1)))
void warp_image(fw_block_t block, __global const FW_T *restrict src, int w, int h,
                __global FW_T *restrict dst, int ow, int oh, float4 cval FW_BATCH_ARGS)
{
    FW_BATCH_SELECT(src, dst, w * h * FW_C, ow * oh * FW_C);
    __local float pos_x[FW_LOCAL_Y * FW_LOCAL_X], pos_y[FW_LOCAL_Y * FW_LOCAL_X];
    int l = get_local_id(0), oy = get_global_id(1);
    int gx0 = get_group_id(0) * FW_LOCAL_X; /* the group's first pixel */
    int row = get_local_id(1) * FW_LOCAL_X; /* the row's part of the local arrays */
    fw_c s = fw_map(block, fw_cx((float)min(gx0 + l, ow - 1), (float)min(oy, oh - 1)));
    pos_x[row + l] = s.re;
    pos_y[row + l] = s.im;
    barrier(CLK_LOCAL_MEM_FENCE);
    if (l >= FW_LOCAL_X / FW_VN || oy >= oh)
        return;
    fw_fv sx = FW_VLOAD(pos_x + row + FW_VN * l), sy = FW_VLOAD(pos_y + row + FW_VN * l);
    fw_pxv v = fw_sample(src, w, h, sx, sy, cval);
    FW_STORE_PIXELS();
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

/* warp_image with antialiasing (fpiwarp/_antialias.py): each pixel the
 * box average of nx x ny sub-samples of its footprint, the parallelogram
 * spanned by the inverse map's Jacobian columns ex, ey at the pixel; nx,
 * ny from the edges' lengths (fw_aa_count). Same work-groups and phases as
 * warp_image: the map and its derivatives per pixel into local memory,
 * then the sampling, FW_VN pixels per work-item, looping over the largest
 * counts of its lanes (lanes with fewer sub-samples skip the extra ones).
 * The plain sample at the pixel is taken only where some lane needs it
 * (one sub-sample): on a PoCL CPU a sample costs about as much in the
 * loop as outside it, so skipping it saves one of the 4 or more. */
__kernel __attribute__((reqd_work_group_size(FW_LOCAL_X, 1, 1)))
void warp_image_aa(fw_block_t block, __global const FW_T *restrict src, int w, int h,
                   __global FW_T *restrict dst, int ow, int oh, float4 cval FW_BATCH_ARGS)
{
    FW_BATCH_SELECT(src, dst, w * h * FW_C, ow * oh * FW_C);
    __local float pos_x[FW_LOCAL_X], pos_y[FW_LOCAL_X];
    __local float exx[FW_LOCAL_X], exy[FW_LOCAL_X], eyx[FW_LOCAL_X], eyy[FW_LOCAL_X];
    int l = get_local_id(0), oy = get_global_id(1);
    int gx0 = get_group_id(0) * FW_LOCAL_X; /* the group's first pixel */
    /* the position exactly as warp_image computes it (so that a magnified
     * pixel is bit for bit the plain one), the derivatives beside it */
    fw_c z = fw_cx((float)min(gx0 + l, ow - 1), (float)oy), dz, dzb;
    fw_c s = fw_map(block, z);
    fw_map_wirtinger(block, z, &dz, &dzb);
    pos_x[l] = s.re;
    pos_y[l] = s.im;
    /* ex = f_z + f_zbar, ey = i (f_z - f_zbar): the Jacobian's columns */
    exx[l] = dz.re + dzb.re;
    exy[l] = dz.im + dzb.im;
    eyx[l] = dzb.im - dz.im;
    eyy[l] = dz.re - dzb.re;
    barrier(CLK_LOCAL_MEM_FENCE);
    /* work-items whose pixels all lie past the row's end (padding) write
     * nothing: their sub-samples would only redo the row's last pixel */
    if (l >= FW_LOCAL_X / FW_VN || gx0 + FW_VN * l >= ow)
        return;
    int at0 = FW_VN * l;
    fw_fv sx = FW_VLOAD(pos_x + at0), sy = FW_VLOAD(pos_y + at0);
    fw_fv ax = FW_VLOAD(exx + at0), ay = FW_VLOAD(exy + at0);
    fw_fv bx = FW_VLOAD(eyx + at0), by = FW_VLOAD(eyy + at0);
    fw_fv nx = fw_aa_count(sqrt(ax * ax + ay * ay)), ny = fw_aa_count(sqrt(bx * bx + by * by));
    fw_pxv v = {0.0f, 0.0f, 0.0f, 0.0f};
    if (fw_aa_lanes_min(nx * ny) == 1.0f)
        v = fw_sample(src, w, h, sx, sy, cval);
    float mx = fw_aa_lanes_max(nx), my = fw_aa_lanes_max(ny);
    if (mx > 1.0f || my > 1.0f) {
        fw_fv acc0 = 0.0f, acc1 = 0.0f, acc2 = 0.0f, acc3 = 0.0f;
        for (float j = 0.0f; j < my; j += 1.0f) {
            fw_fv t = (2.0f * j + 1.0f - ny) / (2.0f * ny);
            for (float i = 0.0f; i < mx; i += 1.0f) {
                fw_fv sub = (2.0f * i + 1.0f - nx) / (2.0f * nx);
                fw_iv live = ((fw_fv)i < nx) & ((fw_fv)j < ny);
                fw_pxv u = fw_sample(src, w, h, sx + (ax * sub + bx * t), sy + (ay * sub + by * t), cval);
#define FW_AA_ADD(k, _) acc##k += select((fw_fv)0.0f, u.c##k, live);
                FW_EACH_C(FW_AA_ADD, _)
#undef FW_AA_ADD
            }
        }
        fw_iv multi = (nx > 1.0f) | (ny > 1.0f);
        fw_iv finite = (fabs(sx) <= FW_COORD_LIMIT) & (fabs(sy) <= FW_COORD_LIMIT);
        fw_fv inv = 1.0f / (nx * ny);
#define FW_AA_PICK(k, _) v.c##k = select(v.c##k, select((fw_fv)cval.s##k, acc##k * inv, finite), multi);
        FW_EACH_C(FW_AA_PICK, _)
#undef FW_AA_PICK
    }
    FW_STORE_PIXELS();
}
#endif
