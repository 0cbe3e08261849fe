"""Record the outputs of a fixed set of warps, to show a refactoring keeps behaviour.

Run it before and after a change and compare the two records::

    python3 tests/record_outputs.py record before.json --arrays before.npz
    # ... change the code ...
    python3 tests/record_outputs.py record after.json --arrays after.npz
    python3 tests/record_outputs.py compare before.json after.json

The record holds a SHA-256 of every output (every available backend x
order x mode x dtype x channel count on two maps and two pictures, the
local, constrained and compound maps, map_points on fixed points, the
parameter blocks, and the command line's output files and their pixels); ``compare`` lists
the cases that differ and, given both ``.npz`` files, how much. Bit
identity is only expected on one machine with the same drivers: this is a
developer's tool, not a test (pytest does not collect it).
"""

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

# Record the tree this script lies in, not whichever checkout an editable
# install points to (a git worktree would otherwise record another tree).
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import fpiwarp  # noqa: E402

ORDERS = (0, 1, 3)
MODES = ("constant", "edge", "reflect", "wrap")
DTYPES = ("uint8", "uint16", "float32")


def _pictures():
    """Two small deterministic pictures: a smooth pattern and noise."""
    h, w = 29, 41
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    smooth = np.stack(
        [0.5 + 0.5 * np.sin(x / 3.0 + k) * np.cos(y / 4.0 - k) for k in range(4)], axis=-1
    )
    noise = np.random.default_rng(7).random((h, w, 4))
    return {"smooth": smooth, "noise": noise}


def _as_dtype(img, dtype):
    if dtype == "float32":
        return img.astype(np.float32)
    top = np.iinfo(dtype).max
    return np.floor(img * top + 0.5).astype(dtype)


def _maps():
    src = [[0, 0], [40, 0], [40, 28], [0, 28]]
    dst = [[3, 2], [37, -1], [42, 27], [-2, 30]]
    fpi = fpiwarp.FPI(src, dst)
    mob_dst = [[1, 1], [39, 3], [36, 26], [2, 25]]
    local = fpiwarp.LocalDeformation([[8, 6], [30, 6], [30, 22], [8, 22]],
                                     [[8, 6], [30, 6], [33, 25], [10, 22]], edges=(0, 2))
    constrained = fpiwarp.ConstrainedFPI([[8, 6], [30, 6], [30, 22], [8, 22]],
                                         [[8, 6], [30, 6], [33, 25], [10, 22]], edges=(1, 3))
    compound = fpiwarp.FPI(src, mob_dst) @ fpi
    return {"fpi": fpi, "fpi2": fpiwarp.FPI(src, mob_dst), "local": local,
            "constrained": constrained, "compound": compound}


def _digest(arr):
    arr = np.ascontiguousarray(arr)
    h = hashlib.sha256()
    h.update(str(arr.dtype).encode() + str(arr.shape).encode())
    h.update(arr.tobytes())
    return h.hexdigest()


def _cases(backends):
    pictures, maps = _pictures(), _maps()
    pts = np.array([[x, y] for x in np.linspace(-20, 60, 9) for y in np.linspace(-15, 45, 7)])
    for name, m in maps.items():
        yield f"params/{name}", lambda m=m: m.params()
    for backend in backends:
        for name, m in maps.items():
            yield f"map_points/{backend}/{name}", lambda m=m, b=backend: fpiwarp.map_points(m, pts, backend=b)
        for pic_name, pic in pictures.items():
            for map_name in ("fpi", "fpi2"):
                for order in ORDERS:
                    for mode in MODES:
                        for dtype in DTYPES:
                            for channels in (1, 3, 4):
                                img = _as_dtype(pic[:, :, :channels], dtype)
                                if channels == 1:
                                    img = img[:, :, 0]
                                key = f"warp/{backend}/{pic_name}/{map_name}/o{order}/{mode}/{dtype}/c{channels}"
                                cval = 0.25 if dtype == "float32" else 7
                                yield key, (lambda img=img, m=maps[map_name], o=order, md=mode, b=backend, c=cval:
                                            fpiwarp.warp_image(img, m, (31, 37), order=o, mode=md, cval=c, backend=b))
        img = _as_dtype(pictures["smooth"][:, :, :3], "uint8")
        for map_name in ("local", "constrained", "compound"):
            for order in ORDERS:
                key = f"warp/{backend}/smooth/{map_name}/o{order}/constant/uint8/c3"
                yield key, (lambda m=maps[map_name], o=order, b=backend, img=img:
                            fpiwarp.warp_image(img, m, order=o, cval=5, backend=b))


def _pixels_digest(path):
    """The decoded pixels of an output file (the file's bytes also depend on
    the encoder's compression settings), read with Pillow directly."""
    from PIL import Image

    with Image.open(path) as im:
        return _digest(np.asarray(im))


def _cli_cases(tmp):
    tmp = Path(tmp)
    sample = Path(fpiwarp.__file__).parent / "data" / "sample.png"
    spec = tmp / "spec.json"
    spec.write_text(json.dumps({"src": [[0, 0], [100, 0], [100, 80], [0, 80]],
                                "dst": [[5, 3], [96, -2], [104, 77], [-3, 84]]}))
    runs = {
        "cli/demo": ["demo", str(tmp / "demo.png"), "--backend", "numpy"],
        "cli/warp": ["warp", str(sample), str(tmp / "warp.png"), "--src", "0,0,100,0,100,80,0,80",
                     "--dst", "5,3,96,-2,104,77,-3,84", "--order", "3", "--mode", "reflect", "--backend", "numpy"],
        "cli/warp-edges": ["warp", str(sample), str(tmp / "edges.png"), "--src", "20,20,80,20,80,60,20,60",
                           "--dst", "20,20,80,20,85,66,22,60", "--edges", "0,2", "--backend", "numpy"],
        "cli/spec": ["warp", str(sample), str(tmp / "spec.png"), "--spec", str(spec), "--output-shape", "90x70",
                     "--backend", "numpy"],
    }
    # every run names its backend: the command line's default is the fastest backend here, which differs
    # between machines (the reference is what a record compares)
    for key, args in runs.items():
        out = Path(args[1] if args[0] == "demo" else args[2])
        env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(Path(fpiwarp.__file__).parents[1]),
                                                            os.environ.get("PYTHONPATH", "")])}
        proc = subprocess.run([sys.executable, "-m", "fpiwarp", *args], capture_output=True, text=True, env=env)
        yield key + "/stdout", proc.stdout.replace(str(tmp), "<tmp>")
        yield key + "/file", hashlib.sha256(out.read_bytes()).hexdigest() if out.exists() else None
        yield key + "/pixels", _pixels_digest(out) if out.exists() else None


def record(path, arrays_path=None, backends=None):
    status = fpiwarp.backend_status()
    backends = backends or [b for b, why in status.items() if why is None]
    digests, arrays = {}, {}
    for key, make in _cases(backends):
        try:
            out = make()
        except Exception as exc:  # record failures as outcomes too
            digests[key] = f"error: {type(exc).__name__}: {exc}"
            continue
        digests[key] = _digest(out)
        arrays[key] = np.asarray(out)
    with tempfile.TemporaryDirectory() as tmp:
        for key, value in _cli_cases(tmp):
            digests[key] = value
    Path(path).write_text(json.dumps({"backends": backends, "digests": digests}, indent=1, sort_keys=True))
    if arrays_path:
        np.savez_compressed(arrays_path, **{k.replace("/", "|"): v for k, v in arrays.items()})
    print(f"{len(digests)} outputs recorded in {path} (backends: {', '.join(backends)})")


def compare(before, after, before_arrays=None, after_arrays=None):
    a = json.loads(Path(before).read_text())["digests"]
    b = json.loads(Path(after).read_text())["digests"]
    arrs = (np.load(before_arrays), np.load(after_arrays)) if before_arrays and after_arrays else None
    differ = [k for k in sorted(set(a) | set(b)) if a.get(k) != b.get(k)]
    for k in differ:
        extra = ""
        if arrs and k.replace("/", "|") in arrs[0] and k.replace("/", "|") in arrs[1]:
            x = arrs[0][k.replace("/", "|")].astype(np.float64)
            y = arrs[1][k.replace("/", "|")].astype(np.float64)
            if x.shape == y.shape:
                d = np.abs(np.nan_to_num(x) - np.nan_to_num(y))
                extra = f" max |diff| {d.max():.3g}, {np.count_nonzero(d)} of {d.size} values"
        print(f"DIFFERS {k}: {str(a.get(k))[:60]} -> {str(b.get(k))[:60]}{extra}")
    print(f"{len(set(a) & set(b)) - len([k for k in differ if k in a and k in b])} identical, "
          f"{len(differ)} differ, of {len(set(a) | set(b))}")
    return 1 if differ else 0


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("record")
    r.add_argument("path")
    r.add_argument("--arrays")
    r.add_argument("--backends", help="comma-separated (default every available one)")
    c = sub.add_parser("compare")
    c.add_argument("before")
    c.add_argument("after")
    c.add_argument("--arrays", nargs=2, metavar=("BEFORE.npz", "AFTER.npz"))
    args = p.parse_args(argv)
    if args.cmd == "record":
        record(args.path, args.arrays, args.backends.split(",") if args.backends else None)
        return 0
    return compare(args.before, args.after, *(args.arrays or ()))


if __name__ == "__main__":
    os.environ.setdefault("PYTHONHASHSEED", "0")
    sys.exit(main())
