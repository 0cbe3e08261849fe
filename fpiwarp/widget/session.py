"""One editing session of the browser page: the Python half of the editor.

The page (static/editor.js) draws; everything that is math happens here,
with the desktop viewer's own logic: :class:`fpiwarp.viewer.Editor` builds
the map from the handles and constrained edges (an FPI, or a
LocalDeformation once two edges are constrained; a degenerate quad keeps
the last good map), measures K, saves the spec and exports. What the
Editor calls its renderer is :class:`PageView`, which draws nothing: it
keeps what the page needs to draw the frame, the parameter block of the
map's inverse (``transform.inverse.params()``, float32 rows of vec4, as the
desktop renderer uploads it) and the program assembled from ``glsl/``
(:mod:`fpiwarp.widget.shaders`).

A drag is a round trip: the page sends the dragged handle's output
position, this side rebuilds the map and sends the new block. The map is
never evaluated in the browser outside the shaders of ``glsl/``.

Messages from the page (dicts, JSON): ``{"type": "move", "index": i,
"xy": [x, y]}`` (drag handle i there), ``{"type": "release"}``,
``{"type": "edge", "index": k}`` (constrain or free edge k),
``{"type": "key", "key": "s"|"e"|"r"|"x"|"f"|"a"}`` (save the spec, export,
reset, clear the edges, fit the view, antialiasing on/off) and ``{"type": "texture_limit", "value": n}``. Each may
carry ``"seq"``, echoed in the state as ``"seq"`` so that the page can
coalesce a drag's moves.
"""

import base64
import itertools
import math

import numpy as np

from ..backends.gl.pyramid import atlas_layout
from ..block import describe
from ..block.sampling_rules import AA_MAX_LEVEL
from ..errors import ArgumentError, FpiwarpError
from ..maps.rlinear import RLinear
from ..maps.transform import Compound
from ..validation import check_image
from ..viewer import overlays as ov
from ..viewer.app import PICK_RADIUS, Editor
from ..viewer.renderer import display_rgba
from ..warping import warp_image
from . import shaders

#: Overlays the page starts with, as the desktop viewer.
DEFAULT_OVERLAYS = ("handles", "outline")
#: Every overlay the page can toggle (H, O, C, D; N all).
OVERLAYS = ("handles", "outline", "checkerboard", "heatmap")
#: A texture side every WebGL2 implementation supports (the page reports its own).
SAFE_TEXTURE_LIMIT = 4096
#: Margin of the fit view around the warped content (a fraction of its larger side).
FIT_MARGIN = 0.05
#: Image versions, unique in the process: a page shown another session's
#: picture reloads it.
_IMAGE_VERSIONS = itertools.count(1)
#: Display textures: value = texel * scale (the desktop renderer's DISPLAY_FORMATS).
DISPLAY_SCALE = {np.dtype(np.uint8): 255.0, np.dtype(np.uint16): 65535.0, np.dtype(np.float32): 1.0}


def _finite_list(a):
    """Nested lists of an array with non-finite values as None (JSON)."""
    a = np.asarray(a, dtype=np.float64)
    return np.where(np.isfinite(a), a, np.nan).tolist() if a.size else []


def _json_floats(values):
    return [None if not math.isfinite(v) else v for v in values]


def display_size(shape, limit):
    """(width, height) of the display texture: the image's size, or scaled
    down to ``limit`` pixels on its longer side (aspect kept)."""
    h, w = shape[:2]
    k = min(1.0, limit / max(h, w))
    return (w, h) if k == 1.0 else (max(1, round(w * k)), max(1, round(h * k)))


def display_image(image, size):
    """The image resized to ``size`` (w, h) for display (area averaging),
    in its own dtype; the image itself at its own size."""
    h, w = image.shape[:2]
    if (w, h) == tuple(size):
        return image
    from PIL import Image

    planes = []
    for c in range(image.shape[2]):
        plane = Image.fromarray(np.ascontiguousarray(image[:, :, c]).astype(np.float32), mode="F")
        planes.append(np.asarray(plane.resize(tuple(size), Image.Resampling.BOX), dtype=np.float32))
    out = np.stack(planes, -1)
    if image.dtype != np.float32:
        out = np.clip(np.floor(out + 0.5), 0, DISPLAY_SCALE[image.dtype])
    return out.astype(image.dtype)


def texture_scale(shape, size):
    """The map from full-size source pixels to display-texture pixels
    (centres at integers: (p + 0.5) * k - 0.5 per axis), or None at 1:1."""
    h, w = shape[:2]
    kx, ky = size[0] / w, size[1] / h
    if kx == 1.0 and ky == 1.0:
        return None
    return RLinear(0.5 * (kx + ky), 0.5 * (kx - ky), complex(0.5 * (kx - 1), 0.5 * (ky - 1)))


class PageView:
    """The renderer :class:`fpiwarp.viewer.Editor` drives, for a page that
    draws in WebGL2: it keeps the block, the overlays' geometry and the view,
    and exports through the Python backends (:meth:`warp_full`)."""

    def __init__(self, *, order=1, mode="constant", cval=0.0, antialias=False, backend=None):
        self.order, self.mode, self.cval = order, mode, cval
        self.antialias = antialias
        self.backend = backend
        self.method = "pixel"  # the page draws per pixel (WebGL2 has no clip distances for the mesh path)
        self.active_handle = None
        self.invalid = False
        self.texture_limit = SAFE_TEXTURE_LIMIT
        self.image = None
        self.transform = None
        self.handles = None
        self.edges = ()
        self.edge_curves = None
        self.view = None

    def set_image(self, image):
        self.image = image
        h, w = image.shape[:2]
        self.view = (-0.5, -0.5, w - 0.5, h - 0.5)

    def set_transform(self, transform, *, handles=None, edges=None):
        self.transform = transform
        steps = getattr(transform, "steps", None)
        step = steps[-1] if steps else transform
        self.handles = None if handles is None else np.asarray(handles, np.float64).reshape(-1, 2)
        self.edges = tuple(getattr(step, "edges", ()) or ()) if edges is None else tuple(edges)
        self.edge_curves = ov.edge_curves(step)

    # Positions the Editor converts are the page's output coordinates already.
    def window_to_output(self, xy, viewport=None):
        return np.asarray(xy, dtype=np.float64)

    def output_to_window(self, pts, viewport=None):
        return np.asarray(pts, dtype=np.float64)

    def view_params(self, viewport=None):
        return (0.0, 0.0, 1.0, 1.0)

    def export_area(self):
        h, w = self.image.shape[:2]
        return (-0.5, -0.5, w - 0.5, h - 0.5)

    def fit(self, margin=FIT_MARGIN):
        """The view that frames the warped content: the export area, the
        handles and the images of the source quad's edges, plus a margin."""
        x0, y0, x1, y1 = self.export_area()
        pts = [np.array([[x0, y0], [x1, y1]])]
        if self.handles is not None:
            pts.append(self.handles)
        if self.edge_curves is not None:
            pts.append(np.asarray(self.edge_curves).reshape(-1, 2))
        pts = np.concatenate(pts)
        pts = pts[np.all(np.isfinite(pts), axis=1)]
        lo, hi = pts.min(0), pts.max(0)
        # a pole near the quad sends edge points far out: keep the view within
        # a few image sizes of the export area
        size = max(x1 - x0, y1 - y0)
        lo = np.maximum(lo, [x0 - 2 * size, y0 - 2 * size])
        hi = np.minimum(hi, [x1 + 2 * size, y1 + 2 * size])
        pad = margin * float(max(hi - lo))
        self.view = (lo[0] - pad, lo[1] - pad, hi[0] + pad, hi[1] + pad)

    def warp_full(self, output_shape=None):
        """The warped image at full resolution through the Python backends."""
        c = self.image.shape[2]
        cval = np.broadcast_to(np.asarray(self.cval, np.float64), (c,))
        out = warp_image(self.image, self.transform, output_shape or self.image.shape[:2], order=self.order,
                         mode=self.mode, cval=cval, antialias=self.antialias, backend=self.backend)
        return out if self.image.ndim == 3 and out.ndim == 3 else out.reshape(self.image.shape)


class Session:
    """The state of one page: an image, the map being edited and the
    settings of the frame; ``handle`` takes the page's messages,
    ``state`` and ``image_payload`` say what to draw.

    Parameters
    ----------
    image : ndarray (H, W) or (H, W, C), uint8, uint16 or float32
    transform : Transform, optional
        The map to start from (default the identity on the image's corners);
        a Compound's last step is edited, the steps before it kept.
    order, mode, cval
        Sampling as in :func:`fpiwarp.warp_image`.
    overlays : sequence of str
        Overlays shown first (of ``OVERLAYS``).
    info, name, spec_path, export_path
        As for the desktop viewer (the S and E keys' files).
    antialias, backend
        How the E key exports (the Python backends).
    background : RGBA 0..1, optional
        What shows where the source is not (images without alpha); default
        cval: the exact warped picture.
    """

    def __init__(self, image, transform=None, *, order=1, mode="constant", cval=0.0, overlays=DEFAULT_OVERLAYS,
                 info=None, name="preview", spec_path=None, export_path=None, antialias=False, backend=None,
                 background=None):
        for o in overlays:
            if o not in OVERLAYS:
                raise ArgumentError(f"overlays: unknown overlay {o!r}; choose from {', '.join(OVERLAYS)}")
        img, _ = check_image(image)
        self.view = PageView(order=order, mode=mode, cval=cval, antialias=antialias, backend=backend)
        self.editor = Editor(self.view, img, transform, info=info, name=name, spec_path=spec_path,
                             export_path=export_path)
        self.view.fit()
        self.overlays = tuple(overlays)
        self.background = background
        self.seq = 0
        self.image_version = next(_IMAGE_VERSIONS)
        self.checker_size = 32.0  # source pixels per checkerboard cell (the desktop renderer's)
        self.checker_mix = 0.35
        self.heat_max = 0.5
        self.heat_mix = 0.6
        self._display = None
        self.programs = {}  # key -> {"key", "vertex", "fragment"}: the programs the page was told of

    # ---- what the page draws
    @property
    def image(self):
        return self.editor.image

    @property
    def transform(self):
        return self.editor.transform

    def set_image(self, image, info=None):
        """Show another picture; the handles stay where they are if it has
        the size of the old one, else they start again on its corners."""
        img, _ = check_image(image)
        e = self.editor
        same = img.shape[:2] == e.image.shape[:2]
        transform = e.transform if same else None
        self.editor = Editor(self.view, img, transform, info=info if info is not None else e.info,
                             spec_path=e.spec_path, export_path=e.export_path)
        self.editor._written = e._written
        self.view.fit()
        self.image_version = next(_IMAGE_VERSIONS)
        self._display = None

    def _display_texture(self):
        size = display_size(self.image.shape, self.view.texture_limit)
        if self._display is None or self._display[0] != size:
            self._display = (size, display_image(self.image, size), texture_scale(self.image.shape, size))
        return self._display

    def display_block(self):
        """The block the page's shader evaluates at each output pixel: the
        inverse of the map, then (for a downscaled display texture) full-size
        source pixels to texture pixels."""
        _, _, scale = self._display_texture()
        inverse = self.transform.inverse
        return (inverse if scale is None else Compound([inverse, scale])).params()

    def image_payload(self):
        """(meta, bytes) of the display texture: its pixels row by row, top
        row first, channels interleaved, in the image's dtype (little-endian)."""
        size, img, _ = self._display_texture()
        meta = {"width": size[0], "height": size[1], "channels": int(img.shape[2]), "dtype": img.dtype.name,
                "version": self.image_version}
        return meta, np.ascontiguousarray(img).astype(img.dtype.newbyteorder("<"), copy=False).tobytes()

    def state(self):
        """Everything the page needs to draw the current frame (JSON-ready)."""
        e, v = self.editor, self.view
        h, w, c = self.image.shape
        size, _, scale = self._display_texture()
        block = self.display_block()
        program = shaders.preview_program(block, order=v.order, mode=v.mode, alpha=c in (2, 4),
                                          antialias=bool(v.antialias))
        atlas_size, levels = atlas_layout(size[1], size[0])
        self.programs[program["key"]] = program
        k = size[0] / w  # display texture pixels per source pixel
        unit = DISPLAY_SCALE[self.image.dtype]
        cval = np.broadcast_to(np.asarray(v.cval, np.float64), (c,)) / unit
        cval4 = display_rgba(cval)
        background = cval4 if self.background is None else np.resize(np.asarray(self.background, np.float64), 4)
        dilation = describe(self.transform.params()).constant_dilation
        return {
            "seq": self.seq,
            "image": {"width": w, "height": h, "channels": c, "dtype": self.image.dtype.name,
                      "display": [size[0], size[1]], "version": self.image_version},
            "block": base64.b64encode(np.ascontiguousarray(block, dtype="<f4").tobytes()).decode("ascii"),
            "block_rows": int(block.shape[0]),
            "program": program["key"],
            "antialias": bool(v.antialias),
            # where the page puts the display texture's pyramid levels (it builds them itself)
            "pyramid": {"size": list(atlas_size), "levels": [list(r) for r in levels], "max_level": AA_MAX_LEVEL},
            "uniforms": {
                "fpw_src_size": [size[0], size[1]],
                "fpw_cval": [float(x) for x in cval4] if c in (2, 4) else [0.0, 0.0, 0.0, 0.0],
                "pv_background": [float(x) for x in background],
                "pv_checker_mix": self.checker_mix,
                "pv_heat_max": self.heat_max,
                "pv_dilation": -1.0 if dilation is None else float(dilation),
            },
            "checker_size": self.checker_size * k,
            "heat_mix": self.heat_mix,
            "src": e.src.tolist(),
            "dst": e.dst.tolist(),
            "edges": list(e.edges),
            "editable": bool(e.editable),
            "curves": _finite_list(v.edge_curves) if v.edge_curves is not None else None,
            "K": float(e.K),
            "title": e.title(),
            "message": e.message,
            "invalid": bool(v.invalid),
            "view": _json_floats(v.view),
            "export_area": list(v.export_area()),
            "overlays": list(self.overlays),
            "pick_radius": PICK_RADIUS,
            "colors": {"handle": ov.HANDLE_COLOR, "active": ov.ACTIVE_COLOR, "edge": ov.EDGE_COLOR,
                       "constrained": ov.CONSTRAINED_COLOR, "ring": ov.RING_COLOR},
            "saved": [str(p) for p in e.saved],
        }

    # ---- the page's messages
    def handle(self, msg):
        """Apply one message from the page (see the module's docstring)."""
        if not isinstance(msg, dict) or "type" not in msg:
            raise ArgumentError(f"a page message must be an object with a 'type', got {msg!r}")
        e = self.editor
        kind = msg["type"]
        if kind == "move":
            i, xy = int(msg["index"]), [float(x) for x in msg["xy"]]
            if not (0 <= i < 4 and len(xy) == 2 and all(math.isfinite(x) for x in xy)):
                raise ArgumentError(f"move: needs a handle index 0..3 and a finite point, got {msg!r}")
            if e.editable:
                e.drag = i
                e.move(xy, None)
        elif kind == "release":
            e.release()
        elif kind == "edge":
            k = int(msg["index"])
            if not 0 <= k < 4:
                raise ArgumentError(f"edge: index must be 0..3, got {k}")
            if e.editable:
                e.toggle_edge(k)
        elif kind == "key":
            key = str(msg["key"]).lower()
            if key not in ("s", "e", "r", "x", "f", "a"):
                raise ArgumentError(f"key: one of s (save spec), e (export), r (reset), x (clear edges), f (fit), "
                                    f"a (antialiasing); got {key!r}")
            try:
                e.key(key)
            except (FpiwarpError, OSError) as exc:
                e.message = " ".join(str(exc).split())
        elif kind == "texture_limit":
            limit = int(msg["value"])
            if limit < 64:
                raise ArgumentError(f"texture_limit: {limit} is not a usable texture size")
            if limit != self.view.texture_limit:
                before = display_size(self.image.shape, self.view.texture_limit)
                self.view.texture_limit = limit
                if display_size(self.image.shape, limit) != before:  # another texture: the page reloads it
                    self._display = None
                    self.image_version = next(_IMAGE_VERSIONS)
        else:
            raise ArgumentError(f"unknown page message type {kind!r}")
        if "seq" in msg:
            self.seq = int(msg["seq"])

    # ---- the same edits from Python
    def set_points(self, src=None, dst=None, edges=None):
        """Set handles and edges from Python (the widget's traits); a map
        that cannot be built raises and keeps the old one."""
        e = self.editor
        old = (e.src.copy(), e.dst.copy(), list(e.edges))
        if src is not None:
            e.src = np.asarray(src, dtype=np.float64).reshape(4, 2).copy()
        if dst is not None:
            e.dst = np.asarray(dst, dtype=np.float64).reshape(4, 2).copy()
        if edges is not None:
            edges = [int(k) for k in edges]
            if len(edges) > 2 or any(not 0 <= k < 4 for k in edges) or len(set(edges)) != len(edges):
                raise ArgumentError(f"edges: at most two different edge numbers 0..3, got {edges}")
            e.edges = edges
        if not e.rebuild():
            message = e.message
            e.src, e.dst, e.edges = old
            e.rebuild()
            raise ArgumentError(f"src/dst/edges: {message}")
