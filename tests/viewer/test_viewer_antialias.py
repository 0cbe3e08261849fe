"""The antialiased on-screen preview: Renderer(antialias=True).draw.

A screen pixel's footprint in the source is the inverse map's Jacobian
times the view's scale. Zooming an identity map out by 4 makes each screen
pixel cover a 4 × 4 block of source pixels exactly (with the default view
fitted to the source), and 4 sub-samples per edge at unit spacing land on
the block's pixels: the antialiased frame is the block mean, while the
plain frame point-samples (aliases). Zoomed in, the draw is the plain one,
bit for bit.
"""

import numpy as np
import pytest

import fpiwarp
from fpiwarp import FPI, RLinear

N, ZOOM = 128, 4


def zone_plate(n):
    """uint8 RGB zone plate reaching the source's Nyquist at the edges."""
    y, x = np.mgrid[0:n, 0:n].astype(np.float64)
    plate = 0.5 + 0.5 * np.cos(np.pi * ((x - n / 2) ** 2 + (y - n / 2) ** 2) / n)
    return np.repeat(np.round(255 * plate).astype(np.uint8)[..., None], 3, axis=-1)


def frame(image, transform, *, antialias, method="pixel", view=None, size=None):
    from fpiwarp.viewer import render_image

    return render_image(image, transform, view=view, size=size,
                        renderer_options={"antialias": antialias, "method": method})


def block_mean(image, k):
    h, w, c = image.shape
    return image.reshape(h // k, k, w // k, k, c).astype(np.float64).mean(axis=(1, 3))


def above_nyquist_energy(img):
    """Energy of the zero-mean picture (channel 0) at frequencies above half
    the output Nyquist (|f| > 1/4 cycle per pixel in x or y)."""
    v = img[..., 0].astype(np.float64)
    spec = np.abs(np.fft.fft2(v - v.mean())) ** 2
    f = np.abs(np.fft.fftfreq(v.shape[0]))
    high = (f[:, None] > 0.25) | (f[None, :] > 0.25)
    return spec[high].sum() / v.size


@pytest.mark.parametrize("method", ["pixel", "mesh"])
def test_zoomed_out_view_is_the_box_filtered_picture(gl_backend, method):
    img = zone_plate(N)
    size = (N // ZOOM, N // ZOOM)
    plain = frame(img, RLinear(1, 0, 0), antialias=False, method=method, size=size)
    smooth = frame(img, RLinear(1, 0, 0), antialias=True, method=method, size=size)
    want = block_mean(img, ZOOM)
    assert np.abs(smooth - want).max() <= 1
    assert np.abs(plain - want).max() > 60  # point samples alias the fine rings
    # what the box removes: the aliased rings' energy at high frequencies
    assert above_nyquist_energy(smooth) < 0.25 * above_nyquist_energy(plain)


def test_zoomed_out_view_is_the_antialiased_warp_of_the_view(gl_backend):
    """The frame of a shrinking map, zoomed out 1/2, is warp_image(antialias=True)
    of that map followed by the view's scaling (screen pixel i at output
    position view0 + 2 i)."""
    img = zone_plate(N)
    f = FPI([[0, 0], [N - 1, 0], [N - 1, N - 1], [0, N - 1]], [[5, 9], [80, 0], [90, 70], [0, 84]])
    size = (48, 48)
    view = (-0.5, -0.5, 2 * size[0] - 0.5, 2 * size[1] - 0.5)
    got = frame(img, f, antialias=True, view=view, size=size)
    screen = RLinear(0.5, 0, -0.25 - 0.25j)  # output x -> screen (x - 0.5) / 2
    want = fpiwarp.warp_image(img, screen @ f, (48, 48),
                              antialias=True, backend="numpy")
    d = np.abs(got.astype(int) - want.astype(int))
    assert np.mean(d <= 2) >= 0.99, f"max diff {d.max()}"


@pytest.mark.parametrize("method", ["pixel", "mesh"])
def test_zoomed_in_view_is_the_plain_draw(gl_backend, method):
    img = zone_plate(N)
    view, size = (30.0, 40.0, 62.0, 72.0), (96, 96)
    f = RLinear(1.1 + 0.2j, 0.05, 3 - 2j)  # magnifies a little
    plain = frame(img, f, antialias=False, method=method, view=view, size=size)
    smooth = frame(img, f, antialias=True, method=method, view=view, size=size)
    assert np.array_equal(plain, smooth)
