// Shading of fpiwarp.gl.Renderer, shared by the per-pixel path
// (preview.frag) and the mesh path (preview_mesh.frag): the source sampled
// at `src`, composited for display, with the optional overlays computed
// from `src` alone: a checkerboard of the SOURCE (cells of pv_checker
// source pixels, so it deforms with the image, like the paper's figures)
// and a heat map of the conformal dilation |f_zbar| / |f_z| coloured from
// dark blue (0, conformal) to dark red (pv_heat_max and above).
// Include after include/fpiwarp.glsl (with FPW_WITH_SAMPLER). Call pv_shade
// from main() unconditionally: it differentiates src between fragments.
// pv_shade_value shades a value the caller sampled (the antialiased
// preview: FPW_ANTIALIAS, see preview.frag).
//
// The source texture is normalized (uint8 / 255, uint16 / 65535) or float;
// the host scales cval alike, and the output is written as is.

// Its per-draw values (fpw_view, pv_background, pv_checker,
// pv_checker_mix, pv_heat, pv_heat_max, pv_dilation: see per_draw.glsl)
// are declared by include/fpiwarp.glsl (FPW_FRAGMENT_PREVIEW*).

// The "jet" colour scale of the paper's figures: dark blue, blue, cyan,
// yellow, red, dark red for t from 0 to 1.
vec3 pv_jet(float t) {
    t = clamp(t, 0.0, 1.0);
    return clamp(vec3(1.5 - abs(4.0 * t - 3.0), 1.5 - abs(4.0 * t - 2.0), 1.5 - abs(4.0 * t - 1.0)), 0.0, 1.0);
}

vec4 pv_shade_value(vec2 src, vec4 c) {
    // Finite differences of the source position between neighbouring
    // fragments (2x2 blocks): the Jacobian of the inverse map per output
    // pixel, whose dilation is the forward map's at src. Computed before
    // any branch (derivatives need uniform control flow).
    vec2 a = dFdx(src) / fpw_view.z;  // d src / d x_out
    vec2 b = dFdy(src) / fpw_view.w;  // d src / d y_out
#ifndef PV_ALPHA
    // Without an alpha channel the texels read alpha 1 and cval is
    // (0, 0, 0, 0): c.a is the weight of the taps inside the image, and
    // "over" the background (= cval for an exact picture) gives the
    // reference's sum of texels and cval exactly.
    c += (1.0 - c.a) * pv_background;
#endif
    bool inside = fpw_in_range(src) && all(greaterThanEqual(src, vec2(-0.5)))
        && all(lessThan(src, vec2(fpw_src_size) - 0.5));
    if (pv_checker > 0.0 && inside) {
        ivec2 cell = ivec2(floor((src + 0.5) / pv_checker));
        c.rgb = mix(c.rgb, vec3(float((cell.x + cell.y) & 1)), pv_checker_mix);
    }
    if (pv_heat > 0.0 && inside) {
        float d = pv_dilation;
        if (d < 0.0) {
            vec2 fz = 0.5 * (a + vec2(b.y, -b.x));   // (f_x - i f_y) / 2
            vec2 fzb = 0.5 * (a + vec2(-b.y, b.x));  // (f_x + i f_y) / 2
            d = length(fzb) / length(fz);
        }
        c.rgb = mix(c.rgb, pv_jet(d / pv_heat_max), pv_heat);
    }
    return c;
}

vec4 pv_shade(vec2 src) {
    return pv_shade_value(src, fpw_sample(src));
}
