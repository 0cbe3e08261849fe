// Per-draw values: the uniforms that fragment programs read for every
// pixel (the source size, cval, the view, the preview's settings), listed
// once here, so that each stage declares them from the same list.
//
// Mesa's llvmpipe loads a uniform again for every pixel, a flat varying
// once per triangle (a 4K warp about twice as fast; GPUs do not care).
// So in a full-screen pass whose host defines FPW_FLAT_PER_DRAW,
// fullscreen.vert declares these uniforms and copies them into the flat
// members of the interface block FpwPerDraw, which the fragment stage
// reads under the same names; elsewhere they are plain uniforms. The host
// sets them by name either way. Values are passed exactly (flat).
//
// FPW_PER_DRAW_VALUES(X) lists the values of the program being built as
// X(type, name); which ones follows the defines both stages see:
//   FPW_WITH_SAMPLER       the sampler and output of include/fpiwarp.glsl;
//   FPW_FRAGMENT_WARP      warp.frag's view (FPW_FRAGMENT_COARSE: coarse.frag's);
//   FPW_FRAGMENT_PREVIEW, FPW_FRAGMENT_PREVIEW_MESH
//                          preview_shade.glsl's view and settings.
// The host budgets FPW_MAX_PER_DRAW varying slots for them (checked below).
// (Directives stay on one line each: GLSL 3.30 has no line continuation.)
// Include once per stage, then expand:
//   FPW_DECLARE_PER_DRAW   in a fragment stage (include/fpiwarp.glsl does);
//   FPW_FORWARD_PER_DRAW_DECLS / FPW_FORWARD_PER_DRAW in fullscreen.vert.

#ifdef FPW_WITH_SAMPLER
#ifdef FPW_TILED
// the texture holds source pixels [x0, x0 + w) × [y0, y0 + h) only;
// fpw_primary is 1 in exactly one pass per output (see fpw_cval_term)
#define FPW_TILE_VALUES(X) X(ivec4, fpw_tile) X(int, fpw_primary)
#else
#define FPW_TILE_VALUES(X)
#endif
#ifdef FPW_HW_FILTER
// 255, 65535 or 1: back from normalized values
#define FPW_FILTER_VALUES(X) X(float, fpw_hw_scale)
#else
#define FPW_FILTER_VALUES(X)
#endif
// The output kinds of fpw_emit: integer ones round and clip to fpw_top,
// float ones scale by fpw_out_scale, sums for tiled sources neither.
#if defined(FPW_ACCUMULATE)
#define FPW_OUTPUT_VALUES(X)
#elif defined(FPW_PACK_PIXELS) || defined(FPW_OUT_INT)
#define FPW_OUTPUT_VALUES(X) X(float, fpw_top)
#elif defined(FPW_OUT_ROUNDED)
#define FPW_OUTPUT_VALUES(X) X(float, fpw_top) X(float, fpw_out_scale)
#else
#define FPW_OUTPUT_VALUES(X) X(float, fpw_out_scale)
#endif
// (W, H) of the whole source image; the value outside ('constant' mode)
// and for non-finite positions
#define FPW_SAMPLER_VALUES(X) X(ivec2, fpw_src_size) X(vec4, fpw_cval) FPW_TILE_VALUES(X) FPW_FILTER_VALUES(X) FPW_OUTPUT_VALUES(X)
#else
#define FPW_SAMPLER_VALUES(X)
#endif

#if defined(FPW_FRAGMENT_WARP) || defined(FPW_FRAGMENT_COARSE)
// out = view.xy + view.zw * (gl_FragCoord.xy - 0.5) (see warp.frag; coarse.frag's nodes alike)
#define FPW_FRAGMENT_VALUES(X) X(vec4, fpw_view)
#elif defined(FPW_FRAGMENT_PREVIEW) || defined(FPW_FRAGMENT_PREVIEW_MESH)
// the view as in warp.frag; what shows where the source is not (sources
// without alpha); the checkerboard's cell in source pixels (0: off) and
// opacity; the heat map's opacity (0: off), the dilation shown dark red,
// and the map's constant dilation (>= 0: an FPI; < 0: per pixel)
#define FPW_FRAGMENT_VALUES(X) X(vec4, fpw_view) X(vec4, pv_background) X(float, pv_checker) X(float, pv_checker_mix) X(float, pv_heat) X(float, pv_heat_max) X(float, pv_dilation)
#else
#define FPW_FRAGMENT_VALUES(X)
#endif

#define FPW_PER_DRAW_VALUES(X) FPW_SAMPLER_VALUES(X) FPW_FRAGMENT_VALUES(X)

// How each stage expands one X(type, name).
#define FPW_PER_DRAW_COUNT_ONE(T, name) + 1
#define FPW_PER_DRAW_UNIFORM(T, name) uniform T name;
#define FPW_PER_DRAW_MEMBER(T, name) flat T name;
#define FPW_PER_DRAW_COPY(T, name) fpw_per_draw.name = name;

#define FPW_PER_DRAW_COUNT (0 FPW_PER_DRAW_VALUES(FPW_PER_DRAW_COUNT_ONE))
#if defined(FPW_MAX_PER_DRAW) && FPW_PER_DRAW_COUNT > FPW_MAX_PER_DRAW
#error "more per-draw values than the host budgets (FPW_MAX_PER_DRAW)"
#endif
#if defined(FPW_FLAT_PER_DRAW) && FPW_PER_DRAW_COUNT == 0
#undef FPW_FLAT_PER_DRAW  // nothing to forward (an interface block cannot be empty)
#endif

#ifdef FPW_FLAT_PER_DRAW
#define FPW_DECLARE_PER_DRAW in FpwPerDraw { FPW_PER_DRAW_VALUES(FPW_PER_DRAW_MEMBER) };
#define FPW_FORWARD_PER_DRAW_DECLS FPW_PER_DRAW_VALUES(FPW_PER_DRAW_UNIFORM) out FpwPerDraw { FPW_PER_DRAW_VALUES(FPW_PER_DRAW_MEMBER) } fpw_per_draw;
#define FPW_FORWARD_PER_DRAW FPW_PER_DRAW_VALUES(FPW_PER_DRAW_COPY)
#else
#define FPW_DECLARE_PER_DRAW FPW_PER_DRAW_VALUES(FPW_PER_DRAW_UNIFORM)
#define FPW_FORWARD_PER_DRAW_DECLS
#define FPW_FORWARD_PER_DRAW
#endif
