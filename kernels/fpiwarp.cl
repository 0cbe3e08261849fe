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

/* out[i] = map(pts[i]) for i < n; points are interleaved (x, y).
 *
 * Work-groups of FW_LOCAL_X points (the host rounds the global size up;
 * padding work-items redo the last point, writing the same value), in
 * phases split by barriers: read the group's x, then y, into local
 * arrays, map them, write x, then y. On a CPU each phase becomes its own
 * loop over work-items and each vectorizes: reading or writing an (x, y)
 * pair in one phase makes a two-lane vector access that stops PoCL's
 * vectorizer. */
__kernel __attribute__((reqd_work_group_size(FW_LOCAL_X, 1, 1)))
void map_points(fw_block_t block, __global const FW_POINT *restrict pts,
                __global FW_POINT *restrict out, int n)
{
    __local float px[FW_LOCAL_X], py[FW_LOCAL_X];
    int i = get_global_id(0), l = get_local_id(0);
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
}

#ifdef FW_T
/* dst (oh x ow x FW_C) = src (h x w x FW_C) sampled at map(x, y) for every
 * output pixel center (x, y); block holds the inverse of the user's map.
 *
 * Work-groups are FW_LOCAL_X x 1 pixels of a row (the host rounds the
 * global size up; padding work-items redo the row's last pixel, writing
 * the same values). Two phases split by a barrier: the map, one pixel per
 * work-item, into local memory (on a CPU, PoCL compiles it into a loop
 * over work-items and vectorizes it); then the sampling, FW_VN pixels per
 * work-item in vector types, by the first FW_LOCAL_X / FW_VN work-items. */
__kernel __attribute__((reqd_work_group_size(FW_LOCAL_X, 1, 1)))
void warp_image(fw_block_t block, __global const FW_T *restrict src, int w, int h,
                __global FW_T *restrict dst, int ow, int oh, float4 cval)
{
    __local float pos_x[FW_LOCAL_X], pos_y[FW_LOCAL_X];
    int l = get_local_id(0), oy = get_global_id(1);
    int gx0 = get_group_id(0) * FW_LOCAL_X; /* the group's first pixel */
    fw_c s = fw_map(block, fw_cx((float)min(gx0 + l, ow - 1), (float)oy));
    pos_x[l] = s.re;
    pos_y[l] = s.im;
    barrier(CLK_LOCAL_MEM_FENCE);
    if (l >= FW_LOCAL_X / FW_VN)
        return;
    fw_fv sx = FW_VLOAD(pos_x + FW_VN * l), sy = FW_VLOAD(pos_y + FW_VN * l);
    fw_pxv v = fw_sample(src, w, h, sx, sy, cval);
#define FW_RESULT(k, _) fw_ov res##k = FW_TO_DTYPE(v.c##k);
    FW_EACH_C(FW_RESULT, _)
    int row = oy * ow;
#define FW_STORE_C(k, lane) dst[at + k] = (FW_T)FW_LANE(res##k, lane);
#define FW_STORE_LANE(lane, _)                                      \
    {                                                               \
        int at = (row + min(gx0 + FW_VN * l + lane, ow - 1)) * FW_C; \
        FW_EACH_C(FW_STORE_C, lane)                                 \
    }
    FW_EACH_LANE(FW_STORE_LANE, _)
}
#endif
