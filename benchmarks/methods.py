"""Four-point deformation methods that no installed library provides.

These are the comparison methods of the paper's §5.1 (Fig. 8) that are
not in OpenCV or scikit-image, written for the quality benchmark only:

- :class:`Bilinear` (BIL): the bilinear map of the source quad's
  parameter square onto the target quad's, composed with the inverse of
  the source quad's bilinear parameterization (Newton's method);
- :class:`MeanValue` (MVC): mean value coordinates of the source quad
  (Floater 2003, in the robust form of Hormann and Floater 2006) applied
  to the target corners;
- :class:`MLSSimilarity` (MLS-SIM): moving least squares with
  similarity transformations (Schaefer, McPhail and Warren 2006), weights
  1 / |p_i - v|^(2 alpha).

Each is a callable on (..., 2) float points returning (..., 2) points,
with a ``jacobian(points)`` returning (..., 2, 2) matrices
[[du/dx, du/dy], [dv/dx, dv/dy]]: analytic for BIL, fourth-order central
differences for MVC and MLS-SIM. Projective (PROJ) and thin-plate
splines (TPS) come from scikit-image (see :func:`projective` and
:func:`thin_plate_spline`).
"""

import numpy as np


def _quad(points, name):
    arr = np.asarray(points, dtype=np.float64)
    if arr.shape != (4, 2) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be four finite (x, y) points, shape (4, 2), got {np.shape(points)}")
    return arr


def _points(points):
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim == 0 or arr.shape[-1] != 2:
        raise ValueError(f"points must have shape (..., 2), got {arr.shape}")
    return arr


def finite_difference_jacobian(f, points, h=1e-5):
    """(..., 2, 2) Jacobian of ``f`` by fourth-order central differences.

    The step is ``h`` times the largest coordinate magnitude (at least 1),
    so the truncation error is ~ (h * scale)**4 relative.
    """
    p = _points(points)
    step = h * max(1.0, float(np.max(np.abs(p))) if p.size else 1.0)
    cols = []
    for e in (np.array([step, 0.0]), np.array([0.0, step])):
        cols.append((8 * (f(p + e) - f(p - e)) - (f(p + 2 * e) - f(p - 2 * e))) / (12 * step))
    return np.stack(cols, axis=-1)


class Bilinear:
    """BIL: the bilinear 4-point warp from quad ``src`` to quad ``dst``.

    With Q(s, t) = (1-s)(1-t) q0 + s(1-t) q1 + s t q2 + (1-s) t q3 the
    bilinear patch of a quad, the map is P_dst ∘ P_src⁻¹. For a
    parallelogram ``src`` P_src is affine, so the map reproduces any affine
    map whose image of ``src`` is ``dst``. P_src⁻¹ is solved in closed
    form (a quadratic); it is meant for points inside (or near) a convex
    ``src``, where P_src is invertible.
    """

    name = "BIL"

    def __init__(self, src, dst):
        self.src = _quad(src, "src")
        self.dst = _quad(dst, "dst")

    @staticmethod
    def _patch(q, s, t):
        s, t = s[..., None], t[..., None]
        return (1 - s) * (1 - t) * q[0] + s * (1 - t) * q[1] + s * t * q[2] + (1 - s) * t * q[3]

    @staticmethod
    def _patch_jacobian(q, s, t):
        """(..., 2, 2): columns dQ/ds, dQ/dt."""
        s, t = s[..., None], t[..., None]
        d_s = (1 - t) * (q[1] - q[0]) + t * (q[2] - q[3])
        d_t = (1 - s) * (q[3] - q[0]) + s * (q[2] - q[1])
        return np.stack([d_s, d_t], axis=-1)

    def parameters(self, points):
        """(s, t) with P_src(s, t) = points, each of shape (...).

        Closed form: with e = q1 - q0, f = q3 - q0, g = q0 - q1 + q2 - q3
        and h = p - q0, t solves cross(g, f) t² + (cross(e, f) + cross(h, g)) t
        + cross(h, e) = 0 (roots in the cancellation-free form); of the two
        roots the one nearer the unit square is kept, then two Newton steps
        polish it.
        """
        p = _points(points)
        q = self.src
        e, f, g = q[1] - q[0], q[3] - q[0], q[0] - q[1] + q[2] - q[3]
        h = p - q[0]

        def cross(a, b):
            return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]

        k2 = cross(g, f)
        k1 = cross(e, f) + cross(h, g)
        k0 = cross(h, e)
        root = np.sqrt(np.maximum(k1 * k1 - 4 * k0 * k2, 0.0))
        big = -0.5 * (k1 + np.where(k1 >= 0, root, -root))
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # a root at infinity: dropped below
            candidates = []
            for t in (k0 / big, big / k2):
                den = e + g * t[..., None]
                use_x = np.abs(den[..., 0]) >= np.abs(den[..., 1])
                num = h - f * t[..., None]
                s = np.where(use_x, num[..., 0] / den[..., 0], num[..., 1] / den[..., 1])
                outside = np.hypot(np.clip(s, 0, 1) - s, np.clip(t, 0, 1) - t)
                candidates.append((s, t, np.where(np.isfinite(outside), outside, np.inf)))
        (s1, t1, d1), (s2, t2, d2) = candidates
        first = d1 <= d2
        s, t = np.where(first, s1, s2), np.where(first, t1, t2)
        for _ in range(2):
            r = self._patch(q, s, t) - p
            jac = self._patch_jacobian(q, s, t)
            det = jac[..., 0, 0] * jac[..., 1, 1] - jac[..., 0, 1] * jac[..., 1, 0]
            ok = np.abs(det) > 0
            safe = np.where(ok, det, 1.0)
            ds = (jac[..., 1, 1] * r[..., 0] - jac[..., 0, 1] * r[..., 1]) / safe
            dt = (jac[..., 0, 0] * r[..., 1] - jac[..., 1, 0] * r[..., 0]) / safe
            s, t = np.where(ok, s - ds, s), np.where(ok, t - dt, t)
        return s, t

    def __call__(self, points):
        s, t = self.parameters(points)
        return self._patch(self.dst, s, t)

    def jacobian(self, points):
        """Analytic: J_dst(s, t) @ inverse(J_src(s, t))."""
        s, t = self.parameters(points)
        return self._patch_jacobian(self.dst, s, t) @ np.linalg.inv(self._patch_jacobian(self.src, s, t))


class MeanValue:
    """MVC: mean value coordinates of polygon ``src`` applied to ``dst``.

    f(p) = sum_i lambda_i(p) dst_i with lambda the mean value coordinates
    of p in the polygon ``src`` (any number of vertices, here 4). They
    sum to one and have linear precision (sum_i lambda_i src_i = p), so f
    reproduces every affine map. The robust formula of Hormann & Floater
    (2006) is used; points on a vertex or an edge get the boundary's
    linear interpolation, so f interpolates the corners exactly.
    """

    name = "MVC"

    def __init__(self, src, dst):
        self.src = np.asarray(src, dtype=np.float64)
        self.dst = np.asarray(dst, dtype=np.float64)
        if self.src.ndim != 2 or self.src.shape[1] != 2 or self.src.shape[0] < 3:
            raise ValueError(f"src must be a polygon of shape (n >= 3, 2), got {self.src.shape}")
        if self.dst.shape != self.src.shape:
            raise ValueError(f"dst must have the shape of src {self.src.shape}, got {self.dst.shape}")

    def coordinates(self, points):
        """(..., n) mean value coordinates of ``points`` in ``src``."""
        p = _points(points)
        v = self.src
        n = v.shape[0]
        d = v - p[..., None, :]  # (..., n, 2): s_i = v_i - p
        r = np.hypot(d[..., 0], d[..., 1])
        d1 = np.roll(d, -1, axis=-2)
        r1 = np.roll(r, -1, axis=-1)
        area = 0.5 * (d[..., 0] * d1[..., 1] - d[..., 1] * d1[..., 0])  # A_i
        dot = d[..., 0] * d1[..., 0] + d[..., 1] * d1[..., 1]  # D_i
        scale = np.max(np.abs(v - v.mean(axis=0)))
        eps = 1e-14 * scale
        with np.errstate(divide="ignore", invalid="ignore"):
            # tan(alpha_i / 2), alpha_i the angle at p in (p, v_i, v_i+1): of its two
            # forms, the one without cancellation (the other loses digits as
            # alpha -> 0, p near an edge's line beyond the edge; it is 0 / 0 on it)
            tan_half = np.where(dot > 0, 2 * area / (r * r1 + dot), (r * r1 - dot) / (2 * area))
            w = (np.roll(tan_half, 1, axis=-1) + tan_half) / r
            lam = w / np.sum(w, axis=-1, keepdims=True)
        # boundary: on vertex i, or on edge i (area_i ~ 0 and dot_i < 0)
        on_vertex = r <= eps
        on_edge = (np.abs(area) <= eps * scale) & (dot < 0) & ~on_vertex & ~np.roll(on_vertex, -1, axis=-1)
        special = np.any(on_vertex, axis=-1) | np.any(on_edge, axis=-1)
        if np.any(special):
            lam = lam.copy()
            for idx in zip(*np.nonzero(special)):
                row = np.zeros(n)
                if np.any(on_vertex[idx]):
                    row[int(np.argmax(on_vertex[idx]))] = 1.0
                else:
                    i = int(np.argmax(on_edge[idx]))
                    u = r[idx][i] / (r[idx][i] + r1[idx][i])
                    row[i], row[(i + 1) % n] = 1 - u, u
                lam[idx] = row
        return lam

    def __call__(self, points):
        return self.coordinates(points) @ self.dst

    def jacobian(self, points):
        return finite_difference_jacobian(self, points)


class MLSSimilarity:
    """MLS-SIM: moving least squares with similarities (Schaefer et al. 2006).

    At each point v, f(v) = a (v - p*) + q* in complex notation, where
    p*, q* are the w-weighted centroids of the control points p_i, q_i with
    w_i = 1 / |p_i - v|^(2 alpha), and a = sum w_i conj(p̂_i) q̂_i /
    sum w_i |p̂_i|² is the best similarity's complex scale-rotation.
    It interpolates the control points (w_i -> inf) and reproduces any
    similarity exactly.
    """

    name = "MLS-SIM"

    def __init__(self, src, dst, alpha=1.0):
        self.src = np.asarray(src, dtype=np.float64)
        self.dst = np.asarray(dst, dtype=np.float64)
        if self.src.ndim != 2 or self.src.shape[1] != 2 or self.src.shape[0] < 2:
            raise ValueError(f"src must be control points of shape (n >= 2, 2), got {self.src.shape}")
        if self.dst.shape != self.src.shape:
            raise ValueError(f"dst must have the shape of src {self.src.shape}, got {self.dst.shape}")
        if not alpha > 0:
            raise ValueError(f"alpha must be positive, got {alpha!r}")
        self.alpha = float(alpha)
        self._p = self.src[:, 0] + 1j * self.src[:, 1]
        self._q = self.dst[:, 0] + 1j * self.dst[:, 1]

    def __call__(self, points):
        pts = _points(points)
        v = pts[..., 0] + 1j * pts[..., 1]
        dist2 = np.abs(self._p - v[..., None]) ** 2
        hit = dist2 == 0
        with np.errstate(divide="ignore", invalid="ignore"):
            w = 1.0 / dist2**self.alpha
            w = np.where(hit.any(axis=-1, keepdims=True), hit.astype(np.float64), w)
            wsum = np.sum(w, axis=-1, keepdims=True)
            p_star = np.sum(w * self._p, axis=-1, keepdims=True) / wsum
            q_star = np.sum(w * self._q, axis=-1, keepdims=True) / wsum
            ph, qh = self._p - p_star, self._q - q_star
            mu = np.sum(w * np.abs(ph) ** 2, axis=-1)
            a = np.sum(w * np.conj(ph) * qh, axis=-1) / mu
            out = a * (v - p_star[..., 0]) + q_star[..., 0]
        # on a control point the fit degenerates (mu = 0): f(p_i) = q_i
        out = np.where(hit.any(axis=-1), q_star[..., 0], out)
        return np.stack([out.real, out.imag], axis=-1)

    def jacobian(self, points):
        return finite_difference_jacobian(self, points)


def from_estimate(cls, src, dst):
    """skimage's ``cls.from_estimate`` (>= 0.26) or the older ``estimate``."""
    if hasattr(cls, "from_estimate"):
        tf = cls.from_estimate(src, dst)
        if not tf:
            raise ValueError(f"{cls.__name__} could not be estimated from these points")
        return tf
    tf = cls()
    if not tf.estimate(src, dst):
        raise ValueError(f"{cls.__name__} could not be estimated from these points")
    return tf


def projective(src, dst):
    """PROJ: the projective map taking quad ``src`` to ``dst`` (skimage)."""
    from skimage.transform import ProjectiveTransform

    return from_estimate(ProjectiveTransform, np.asarray(src, float), np.asarray(dst, float))


def thin_plate_spline(src, dst):
    """TPS through the control points: skimage's ThinPlateSplineTransform
    when the installed scikit-image has it (>= 0.24), else scipy's
    RBFInterpolator with the thin_plate_spline kernel. Returns (callable,
    provider name)."""
    src, dst = np.asarray(src, float), np.asarray(dst, float)
    try:
        from skimage.transform import ThinPlateSplineTransform
    except ImportError:
        from scipy.interpolate import RBFInterpolator

        rbf = RBFInterpolator(src, dst, kernel="thin_plate_spline")
        return (lambda p: rbf(np.asarray(p, float).reshape(-1, 2)).reshape(np.shape(p))), "scipy RBFInterpolator"
    tps = from_estimate(ThinPlateSplineTransform, src, dst)
    return (lambda p: tps(np.asarray(p, float).reshape(-1, 2)).reshape(np.shape(p))), "skimage ThinPlateSplineTransform"
