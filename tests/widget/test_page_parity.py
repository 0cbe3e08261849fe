"""The browser's frame equals warp_image(..., backend="numpy"): the page's
WebGL2 program (glsl/ assembled as GLSL ES 3.00) in headless Chromium."""

import numpy as np
import pytest

import fpiwarp
from fpiwarp import FPI, Compound, LocalDeformation
from fpiwarp.widget import browser, shaders
from fpiwarp.widget.session import Session

H, W = 54, 72
SRC = np.array([[0, 0], [W - 1, 0], [W - 1, H - 1], [0, H - 1]], float)
DST = np.array([[5, 3], [W - 4, -5], [W + 4, H + 2], [-4, H - 6]], float)
MAPS = {
    "fpi": lambda: FPI(SRC, DST),
    # over the picture's extent, as the page's editor builds it (and fpiwarp warp)
    "local": lambda: LocalDeformation(SRC, DST, edges=(0, 2), extent=(W, H)),
    "compound": lambda: Compound([FPI(SRC, DST), FPI(DST, SRC + [[3, -2], [-2, 4], [1, 3], [2, -1]])]),
}


def picture(dtype):
    """Ramps, a sinusoid and noise: every sampling order sees a difference.

    The 16-bit picture is smoother, within what float32 kernels hold to 2
    levels of 65535: the inverse of a LocalDeformation stops its Newton
    steps within 5e-5 of its spline's radius (~2e-3 px for a picture this
    size with the picture's extent), and a value moves by gradient x
    position error."""
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    rng = np.random.default_rng(7)
    if dtype == np.uint16:
        gray = 0.55 * x / (W - 1) + 0.3 * y / (H - 1) + 0.1 * (0.5 + 0.5 * np.sin(x / 6.0) * np.cos(y / 8.0))
        return np.round((gray + 0.02 * rng.random((H, W))) * 65535).astype(np.uint16)  # gray, 16 bits
    chans = [x / (W - 1), y / (H - 1), 0.5 + 0.5 * np.sin(x / 3.0) * np.cos(y / 4.0)]
    base = np.stack(chans, -1) * 0.8 + 0.2 * rng.random((H, W, 3))
    return np.round(base * 255).astype(np.uint8)


def close_share(a, b, levels):
    return float(np.mean(np.abs(a.astype(np.float64) - b.astype(np.float64)).reshape(H, W, -1).max(-1) <= levels))


def shares(driver, show, name, order, dtype):
    """{what: share of pixels within 2 levels of the numpy warp} of the
    frame the page draws for MAPS[name] at ``order`` on picture(dtype):
    "shown" (the canvas, 8 bits) and for 16-bit pictures "levels" (the
    same program into a float target: the 16-bit levels, rounded and
    clipped as warp_image's to_dtype does). Also benchmarks/browser_preview.py's
    parity table."""
    img = picture(dtype)
    f = MAPS[name]()
    show(Session(img, f, order=order, overlays=()))
    ref = fpiwarp.warp_image(img, f, order=order, backend="numpy")
    shown = browser.capture(driver)  # the canvas as drawn, 8 bits
    if dtype == np.uint8:
        return {"shown": close_share(shown[:, :, :3], ref, 2)}
    values = np.clip(np.floor(browser.capture(driver, fmt="float")[:, :, 0] * 65535.0 + 0.5), 0, 65535)
    return {"levels": close_share(values, ref, 2), "shown": close_share(shown[:, :, 0], np.round(ref / 257.0), 2)}


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16], ids=["uint8", "uint16"])
@pytest.mark.parametrize("order", [0, 1, 3])
@pytest.mark.parametrize("name", list(MAPS))
def test_browser_frame_equals_numpy(page, dtype, order, name):
    driver, _, show = page
    got = shares(driver, show, name, order, dtype)
    assert min(got.values()) >= 0.99, f"{name} order {order} {np.dtype(dtype).name}: {got}"
    assert not browser.console_problems(driver)


def test_page_compiles_only_programs_assembled_from_glsl(page):
    """What the browser compiled is, byte for byte, the ES assembly of the
    glsl/ files with the block contract's constants."""
    driver, _, show = page
    img = picture(np.uint8)
    for f in (FPI(SRC, DST), LocalDeformation(SRC, DST, edges=(1, 3))):
        show(Session(img, f, overlays=()))
    compiled = driver.execute_script("return window.fpiwarpEditor.compiled;")
    assert len(compiled) >= 2
    from fpiwarp import glsl
    from fpiwarp.block.codegen import glsl_defines

    for entry in compiled:
        assert entry["vertex"].startswith("#version 300 es\n") and entry["fragment"].startswith("#version 300 es\n")
        for name, value in glsl_defines().items():
            assert f"#define {name} {value}\n" in entry["fragment"]
        for part in ("include/map.glsl", "include/sample.glsl", "include/antialias.glsl", "viewer/preview_shade.glsl"):
            assert glsl.read(part).strip() in entry["fragment"]
        assert glsl.read(glsl.FULLSCREEN_VERT).split("\n", 1)[1].split('#include')[0] in entry["vertex"]
    for f in (FPI(SRC, DST), LocalDeformation(SRC, DST, edges=(1, 3))):
        key = shaders.preview_key(f.inverse.params(), order=1, mode="constant", alpha=False)
        vertex, fragment = shaders.program_sources(key)
        assert any(e["vertex"] == vertex and e["fragment"] == fragment for e in compiled)
