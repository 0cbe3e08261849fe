"""The gallery's reading order: from a first warp to embedding the renderer
(sphinx-gallery imports this by name: ``within_subsection_order``)."""

from pathlib import Path

ORDER = [
    "plot_fpi_photo.py",
    "plot_fpi_anatomy.py",
    "plot_compare_methods.py",
    "plot_fpi_curve.py",
    "plot_local_deformation.py",
    "plot_compound.py",
    "plot_antialias.py",
    "plot_map_points_mesh.py",
    "plot_source_positions.py",
    "plot_torch_registration.py",
    "plot_batch_folder.py",
    "plot_embed_renderer.py",
]


class ExampleOrder:
    """Sort key: an example's place in ORDER; examples not listed come last, by name."""

    def __init__(self, src_dir):
        self.src_dir = src_dir

    def __call__(self, filename):
        name = Path(filename).name
        return (ORDER.index(name), "") if name in ORDER else (len(ORDER), name)

    def __repr__(self):
        return f"<{type(self).__name__}>"
