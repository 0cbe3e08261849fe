"""
Warping a folder of images
==========================

One map, many files: :func:`fpiwarp.batch.run_batch` (the
``fpiwarp batch`` command) warps every image of a folder into another
folder, keeping each file's name, format, bit depth and metadata. Outputs
that exist are skipped, so a rerun resumes. The map comes from a JSON spec
(:func:`fpiwarp.spec.save_spec`), the same file the command line reads.
"""

import subprocess
import sys
import tempfile
from importlib import resources
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import fpiwarp
from fpiwarp.batch import run_batch
from fpiwarp.spec import save_spec

with resources.as_file(resources.files("fpiwarp.data") / "sample.png") as path:
    image = fpiwarp.read_image(path)

# %%
# A folder of three small PNG files: crops of the sample picture.
work = Path(tempfile.mkdtemp())
inputs, outputs = work / "photos", work / "warped"
inputs.mkdir()
for i, (r, c) in enumerate([(0, 0), (120, 200), (240, 400)]):
    fpiwarp.write_image(inputs / f"crop{i}.png", image[r:r + 200, c:c + 240])

corners = [[0, 0], [239, 0], [239, 199], [0, 199]]
f = fpiwarp.FPI(corners, [[20, 10], [230, 0], [239, 199], [10, 180]])
save_spec(f, work / "warp.json")

# %%
# In Python: the summary counts what was done, skipped and failed.
summary = run_batch(f, inputs, outputs, jobs=2)
print("\n".join(summary.report()))

# %%
# The same from the command line; a rerun skips what exists.
cmd = [sys.executable, "-m", "fpiwarp", "batch", str(work / "warp.json"), str(inputs), str(outputs)]
print(subprocess.run(cmd, capture_output=True, text=True, check=True).stdout)

files = sorted(outputs.glob("*.png"))
fig, axes = plt.subplots(2, len(files), figsize=(9, 4.4))
for col, out in enumerate(files):
    axes[0, col].imshow(fpiwarp.read_image(inputs / out.name))
    axes[0, col].set_title(f"photos/{out.name}")
    axes[1, col].imshow(fpiwarp.read_image(out))
    axes[1, col].set_title(f"warped/{out.name}")
for ax in axes.flat:
    ax.set_axis_off()
fig.tight_layout()
plt.show()
print("the inputs are unchanged:", np.array_equal(fpiwarp.read_image(inputs / "crop0.png"), image[:200, :240]))
