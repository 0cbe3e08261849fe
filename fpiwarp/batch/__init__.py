"""Batches: many images or point sets, arrays and stacks, folders and files, Dask.

* :mod:`.images`: :func:`warp_images` (a generator) and :func:`warp_batch`
  (an (N, H, W[, C]) stack, one map or one per image);
* :mod:`.points`: :func:`map_points_batch`;
* :mod:`.arrays`: both for every kind of device array;
* :mod:`.folders`, :mod:`.files`: a folder of image files into another;
* :mod:`.dask`: the same on a Dask cluster;
* :mod:`.progress`: the progress bar of folder batches (tqdm when installed).
"""

from .folders import BatchSummary, run_batch
from .images import warp_batch, warp_images
from .points import map_points_batch

__all__ = ["BatchSummary", "map_points_batch", "run_batch", "warp_batch", "warp_images"]
