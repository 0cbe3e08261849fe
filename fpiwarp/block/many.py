"""The parameter blocks of many maps at once, for batches.

A batch of N maps needs N blocks stacked into one (N, rows, 4) float32
array and grouped by kind of map. :func:`pack_many` writes the stages of
all maps in one pass (the eight fixed rows of every stage as one numpy
assignment; only seed tables, regions and TPS centers stage by stage),
and :meth:`BlockStack.groups` describes each distinct header once rather
than each block. Block ``i`` of the stack equals ``pack(stage_lists[i])``
bit for bit, followed by zero rows up to the longest block (rows past a
block's stages are never read).
"""

from dataclasses import dataclass

import numpy as np

from .describe import describe
from .layout import CORE_AFFINE, LAYOUT_VERSION, MAX_STAGES, ROW_REGIONS, STAGE_ROWS
from .pack import check_stage, fixed_values, write_tables

#: Rows 0 .. FIXED_ROWS - 1 of a stage, which every stage fills (:func:`fixed_values`).
FIXED_ROWS = ROW_REGIONS


def _has_tables(st):
    return st.seed is not None or len(st.regions) > 0 or len(st.centers) > 0


def pack_many(stage_lists):
    """The blocks of many maps' stages: (N, rows, 4) float32, block ``i``
    equal to ``pack(stage_lists[i])`` bit for bit, then zero rows up to the
    longest block. Raises ValueError as :func:`fpiwarp.block.pack` does."""
    stage_lists = [list(stages) for stages in stage_lists]
    counts = np.array([len(stages) for stages in stage_lists], dtype=np.int64)
    for count in counts:
        if not 1 <= count <= MAX_STAGES:
            raise ValueError(f"a map packs into 1 to {MAX_STAGES} stages, this one needs {count}")
    flat = [st for stages in stage_lists for st in stages]
    for st in flat:
        check_stage(st)
    out = np.zeros((len(stage_lists), 1 + int(counts.max()) * STAGE_ROWS, 4), dtype=np.float64)
    out[:, 0, 0], out[:, 0, 1] = counts, LAYOUT_VERSION
    values = np.array([fixed_values(st) for st in flat], dtype=np.float64).reshape(-1, FIXED_ROWS, 4)
    owner = np.repeat(np.arange(len(stage_lists)), counts)
    first = 1 + STAGE_ROWS * np.concatenate([np.arange(c) for c in counts])
    out[owner[:, None], first[:, None] + np.arange(FIXED_ROWS)] = values
    for j, st in enumerate(flat):
        if _has_tables(st):
            write_tables(out[owner[j], first[j] : first[j] + STAGE_ROWS], st)
    return out.astype(np.float32)


def is_many_maps(transforms):
    """Whether ``transforms`` is one object holding many maps as arrays (a
    :class:`fpiwarp.maps.fpi.FPIStack`: ``block_stack()`` and ``inverse``)
    rather than a sequence of map objects."""
    return hasattr(transforms, "block_stack")


def inverses(transforms):
    """The inverses of a batch's maps as :meth:`BlockStack.of` takes them:
    the many-maps object's ``inverse`` (no object per map), or a list."""
    if is_many_maps(transforms):
        return transforms.inverse
    return [t.inverse for t in transforms]


@dataclass(frozen=True)
class BlockStack:
    """Stacked float32 blocks of N maps: ``array`` (N, rows, 4), block
    ``i`` in its first ``rows[i]`` rows (zero rows after)."""

    array: np.ndarray
    rows: np.ndarray

    @classmethod
    def of(cls, transforms):
        """The blocks of ``transforms`` (anything with ``stages()``: maps,
        or the inverse blocks the batch paths compute once)."""
        if is_many_maps(transforms):  # e.g. fpiwarp.maps.fpi.FPIStack: packed in one pass by the maps themselves
            return transforms.block_stack()
        array = pack_many([t.stages() for t in transforms])
        return cls(array, 1 + STAGE_ROWS * array[:, 0, 0].astype(np.int64))

    @classmethod
    def from_blocks(cls, blocks):
        """A stack of given blocks ((rows, 4) arrays, e.g. ``params()``), or
        ``blocks`` itself when it is a BlockStack already."""
        if isinstance(blocks, cls):
            return blocks
        blocks = [np.asarray(b, dtype=np.float32) for b in blocks]
        rows = np.array([b.shape[0] for b in blocks], dtype=np.int64)
        array = np.zeros((len(blocks), int(rows.max()), 4), dtype=np.float32)
        for i, b in enumerate(blocks):
            array[i, : rows[i]] = b
        return cls(array, rows)

    def __len__(self):
        return len(self.array)

    def blocks(self):
        """Each block alone, as ``Transform.params()`` gives it (views)."""
        return [self.array[i, :r] for i, r in enumerate(self.rows)]

    def take(self, idx):
        """(rows, (len(idx), rows, 4) float32): blocks ``idx`` padded to the
        longest of them."""
        rows = int(self.rows[idx].max())
        return rows, np.ascontiguousarray(self.array[idx, :rows])

    def groups(self, key):
        """[(key, indices (k,) int32)]: the blocks grouped by ``key(kind)``
        of their :class:`~fpiwarp.block.BlockKind`, in order of first
        appearance, indices increasing. Each distinct header (the stage
        count and every stage's header row) is described once, so ``key``
        must read only what the header decides (``stages``, ``is_short``),
        never ``constant_dilation``. A block no kernel knows raises
        ValueError (:func:`fpiwarp.block.describe`)."""
        heads = self.array[:, 1::STAGE_ROWS][:, : (self.array.shape[1] - 1) // STAGE_ROWS]
        sig = np.concatenate([self.array[:, 0], heads.reshape(len(self), -1)], axis=1)
        _, first, inverse = np.unique(sig, axis=0, return_index=True, return_inverse=True)
        inverse = inverse.reshape(-1)
        found = {}
        for u in np.argsort(first, kind="stable"):
            i = int(first[u])
            k = key(describe(self.array[i, : self.rows[i]]))
            found.setdefault(k, []).append(u)
        return [(k, np.flatnonzero(np.isin(inverse, us)).astype(np.int32)) for k, us in found.items()]


def pack_one_stage(pre_center, pre_pole, pre_scale, post_scale, post_pole, post_offset, l1, l2, l3):
    """The blocks of N one-stage affine-core maps from their parts as
    complex arrays (N,) (the :class:`~fpiwarp.block.Stage` fields
    ``pre.center``, ``pre.inverse_pole``, ``pre.scale``, ``post.scale``,
    ``post.inverse_pole``, ``post.offset``, ``linear.l1/l2/l3``), written
    in one pass without a Stage per map: a :class:`BlockStack` whose block
    ``i`` equals ``pack([Stage(...)])`` of map i's parts (the Newton seed
    row, the R-linear inverse, in the vectorised form of
    :func:`fpiwarp.block.pack.rlinear_inverse`, within 1 float32 ulp).
    Raises ValueError for a singular or non-finite R-linear part."""
    parts = [np.asarray(v, dtype=np.complex128).reshape(-1) for v in
             (pre_center, pre_pole, pre_scale, post_scale, post_pole, post_offset, l1, l2, l3)]
    n = len(parts[0])
    m1, m2, m3 = rlinear_inverse_many(parts[6], parts[7], parts[8])
    out = np.zeros((n, 1 + STAGE_ROWS, 4), dtype=np.float32)  # float64 values rounded once, as pack() does
    out[:, 0, 0], out[:, 0, 1] = 1, LAYOUT_VERSION
    fixed = out[:, 1:1 + FIXED_ROWS].reshape(n, FIXED_ROWS * 2, 2)  # (re, im) pairs in row order
    # rows: header, pre (center, pole), scales (pre, post), post (pole, offset), (l1, l2), (l3, tol 0), mu12, mu3
    pairs = (None, None, parts[0], parts[1], parts[2], parts[3], parts[4], parts[5], parts[6], parts[7], parts[8],
             None, m1, m2, m3, None)
    for k, v in enumerate(pairs):
        if v is not None:
            fixed[:, k, 0], fixed[:, k, 1] = v.real, v.imag
    out[:, 1, 0] = CORE_AFFINE  # the stage's header: no centers, regions or Newton iterations
    return BlockStack(out, np.full(n, 1 + STAGE_ROWS, dtype=np.int64))


def rlinear_inverse_many(l1, l2, l3):
    """:func:`fpiwarp.block.pack.rlinear_inverse` of N R-linear parts
    (complex arrays): (m1, m2, m3); ValueError where one is singular,
    not finite or its |l1|² - |l2|² leaves float64's normal range."""
    a, b = np.abs(l1), np.abs(l2)
    with np.errstate(all="ignore"):
        det = a * a - b * b
        bad = ~(np.isfinite(l1) & np.isfinite(l2) & np.isfinite(l3)) | (np.abs(a - b) <= 1e-14 * (a + b)) | \
            ~(np.abs(det) < np.inf) | (np.abs(det) < np.finfo(np.float64).tiny)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"R-linear part {i} ({l1[i]}, {l2[i]}, {l3[i]}) cannot be inverted: singular, not finite or "
                         "|l1|² - |l2|² outside float64's normal range")
    m1 = np.conj(l1) / det
    m2 = -l2 / det
    return m1, m2, -(m1 * l3 + m2 * np.conj(l3))
