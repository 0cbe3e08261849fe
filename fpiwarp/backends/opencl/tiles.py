"""Work-group tiles of the ``"opencl"`` backend's warp_image on CPUs.

The tile is measured per device (:mod:`.tuning`); the history below is
how tiles came to be.

warp_image's work-groups were one row's pixels (``launch_width``). On a
CPU (PoCL), a group is one task for one thread, and the threads take
groups in turn, so a thread's consecutive groups were rows far apart and
each group read its source rows afresh. Tiles several rows high keep a
group's source rows in the cache: neighbouring output rows read mostly
the same source rows (a bilinear tap pair reads two). At 4K, 64 x 8 tiles
ran the uint8 and float32 kernels 15-20 % faster than groups of 960 x 1
(same outputs bit for bit; measured side by side, see the branch notes).

Devices that are not CPUs, antialiased warps (their kernel keeps
one-row groups) and maps with a Newton inverse keep one-row groups: with
64 x 8 tiles, PoCL 3.1 gave a NaN (cval) for a pixel beside ones whose
Newton iteration fails, where one-row groups and the reference converge
(tests/batch/test_batch_launch.py found it; the Newton loop's exit is data
dependent, see fw_newton in fpiwarp_map.h). A Newton map's time is its
map, not its sampling, so tiles would gain it little anyway. Those keep
one-row groups (``opencl_backend.launch_width``). This module imports no
other backend module: the backend passes itself in.
"""

from .tuning import tile_for, usable

#: Tile width (pixels) and height (rows) on CPUs until one is measured for
#: the device (:mod:`.tuning`); the width is a multiple of the 8 pixels one
#: work-item samples (VECTOR_LANES_CPU).
TILE_X_CPU, TILE_ROWS_CPU = 64, 8


def has_newton(kind):
    """Whether a map of ``kind`` (``kind_options``: one ``-DFW_KIND_k=core,
    n_centers, n_regions, newton_iters`` per stage) runs a Newton iteration."""
    return any(int(option.rsplit(",", 1)[1]) > 0 for option in kind)


def tiled(backend, antialias=False, kind=()):
    """Whether warp_image runs in tiles on ``backend``: CPUs (vector lanes),
    not antialiased, no Newton iteration in the map, tiles within the
    device's group size."""
    return backend.lanes > 1 and not antialias and not has_newton(kind) and usable(backend, tile_for(backend))


def tiled_program(backend, dtype, channels, order, mode, width, antialias, kind):
    """(kernel name, build options, (local_x, local_y)) of warp_image for one
    kind of call: ``backend.image_program``'s, with a tile where :func:`tiled`."""
    name, options, local_x = backend.image_program(dtype, channels, order, mode, width, antialias, kind)
    if not tiled(backend, antialias, kind):
        return name, options, (local_x, 1)
    options = tuple(o for o in options if not o.startswith("-DFW_LOCAL_X="))
    x, y = tile_for(backend)
    return name, (*options, f"-DFW_LOCAL_X={x}", f"-DFW_LOCAL_Y={y}"), (x, y)


def global_size(local, output_shape):
    """The launch's global size: the output (rows, cols) rounded up to whole tiles."""
    (local_x, local_y), (oh, ow) = local, output_shape
    return -(-ow // local_x) * local_x, -(-oh // local_y) * local_y
