"""The fast default (fpiwarp.backends.default): backend=None on numpy images
runs a working backend chosen by a measurement cached on disk, falls back
past a backend whose kernels do not build (the reason kept for
backend_status), obeys the switch that disables it, and never measures on
import."""

import json
import os
import subprocess
import sys
import threading

import numpy as np
import pytest
from support import ROOT

import fpiwarp
from fpiwarp.backends import REGISTRY, backend_reason, backend_status, default

F = fpiwarp.FPI([[0, 0], [40, 0], [40, 30], [0, 30]], [[2, 1], [38, -2], [43, 31], [-1, 29]])


@pytest.fixture
def fresh(monkeypatch, tmp_path):
    """The default's state forgotten, a cache folder of its own, the switches
    unset; afterwards the opencl backend's launch shape as it was (the
    calibration tunes it: later tests then build their programs as before)."""
    monkeypatch.setenv(default.ENV_CACHE_DIR, str(tmp_path))
    monkeypatch.delenv(default.ENV_DEFAULT, raising=False)
    monkeypatch.delenv(default.ENV_CALIBRATE, raising=False)
    default.set_default_backend(None)
    default.reset(disk=False)
    saved = dict(fpiwarp.backends._failed)
    shape = launch_shape(fpiwarp.backends._instances.get("opencl"))
    yield tmp_path
    fpiwarp.backends._failed.clear()
    fpiwarp.backends._failed.update(saved)
    default.set_default_backend(None)
    default.reset(disk=False)
    restore_launch_shape(fpiwarp.backends._instances.get("opencl"), shape)


def launch_shape(be):
    """(tile, lanes) of an opencl backend object, None if there is none."""
    return None if be is None else (be.__dict__.get("_tile"), be.lanes)


def restore_launch_shape(be, shape):
    """The tile and width ``be`` had (``shape``), or a new backend's
    (untuned: no tile file in the session's cache) where it was made since."""
    if be is None or be.lanes == 1:
        return
    if shape is None:
        from fpiwarp.backends.opencl import tuning

        shape = (None, int(os.environ.get(tuning.ENV_LANES) or tuning.DEFAULT_LANES))
    if launch_shape(be) != shape:
        be._tile, be.lanes = shape
        be._jobs.clear()  # jobs prepared with the tuned shape


def image(dtype=np.uint8, shape=(31, 41, 3)):
    rng = np.random.default_rng(1)
    if dtype == np.float32:
        return rng.random(shape, dtype=np.float32)
    return rng.integers(0, 256, size=shape, dtype=dtype)


def test_the_default_picks_a_working_backend_and_stays_near_the_reference(fresh):
    chosen = fpiwarp.default_backend()
    assert chosen in REGISTRY and backend_reason(chosen) is None
    ranking = default.ranking()
    assert ranking[-1] == "numpy" and chosen == ranking[0]
    for dtype in (np.uint8, np.uint16, np.float32):
        img = image(dtype)
        got = fpiwarp.warp_image(img, F)
        ref = fpiwarp.warp_image(img, F, backend="numpy")
        assert got.dtype == ref.dtype and got.shape == ref.shape
        tol = 2e-3 if dtype == np.float32 else 1  # the kernels' stated parity: float32 map, one level when rounding
        assert np.abs(got.astype(float) - ref.astype(float)).max() <= tol
        np.testing.assert_array_equal(got, fpiwarp.warp_image(img, F, backend=fpiwarp.backends.default.host_backend(
            img.dtype)))


def test_the_measurement_is_cached_on_disk_and_reused(fresh, monkeypatch):
    fpiwarp.default_backend()
    files = list(fresh.glob("default-backend-*.json"))
    assert len(files) == 1
    record = json.loads(files[0].read_text())
    assert record["key"] == json.loads(json.dumps(default.machine_key())) and record["ranking"] == default.ranking()
    assert set(record["seconds"]) <= set(REGISTRY) and record["ranking"][-1] == "numpy"
    default.reset(disk=False)
    monkeypatch.setattr(default, "calibrate", lambda: pytest.fail("measured again although the file holds it"))
    assert default.ranking() == record["ranking"]


def test_another_machine_key_measures_again(fresh, monkeypatch):
    fpiwarp.default_backend()
    key = default.machine_key()
    monkeypatch.setattr(default, "machine_key", lambda: {**key, "cpu": "another CPU"})
    default.reset(disk=False)
    calls = []
    real = default.calibrate
    monkeypatch.setattr(default, "calibrate", lambda: calls.append(1) or real())
    default.ranking()
    assert calls == [1] and len(list(fresh.glob("default-backend-*.json"))) == 2


def test_reset_forgets_the_measurement(fresh):
    fpiwarp.default_backend()
    assert list(fresh.glob("default-backend-*.json"))
    default.reset()
    assert not list(fresh.glob("default-backend-*.json"))


def test_the_switch_and_set_default_backend(fresh, monkeypatch):
    monkeypatch.setattr(default, "calibrate", lambda: pytest.fail("measured although the default is named"))
    img = image()
    monkeypatch.setenv(default.ENV_DEFAULT, "numpy")
    assert fpiwarp.default_backend() == "numpy"
    np.testing.assert_array_equal(fpiwarp.warp_image(img, F), fpiwarp.warp_image(img, F, backend="numpy"))
    monkeypatch.setenv(default.ENV_DEFAULT, "nope")
    with pytest.raises(fpiwarp.ArgumentError, match="FPIWARP_DEFAULT_BACKEND='nope' names no backend"):
        fpiwarp.warp_image(img, F)
    monkeypatch.delenv(default.ENV_DEFAULT)
    fpiwarp.set_default_backend("numpy")
    assert fpiwarp.Warper(F).backend == "numpy"
    with pytest.raises(fpiwarp.ArgumentError, match="unknown backend"):
        fpiwarp.set_default_backend("nope")


def test_calibration_off_ranks_by_the_registry(fresh, monkeypatch):
    monkeypatch.setenv(default.ENV_CALIBRATE, "0")
    monkeypatch.setattr(default, "calibrate", lambda: pytest.fail("measured although FPIWARP_CALIBRATE=0"))
    ranking = default.ranking()
    auto = [name for name, entry in REGISTRY.items() if entry.auto]
    assert ranking[-1] == "numpy" and sorted(ranking[:-1]) == sorted(auto)
    assert ranking.index("warp") == len(ranking) - 2  # slow to build on a CPU: last of the kernels
    assert not list(fresh.glob("default-backend-*.json"))
    assert fpiwarp.default_backend() in REGISTRY


def test_a_backend_whose_kernels_fail_to_build_is_skipped_with_its_reason(fresh, monkeypatch):
    """What the pip-only PoCL 3.0-rc2 does on an AVX-512 CPU, simulated: every
    build raises pyopencl's RuntimeError with its log."""
    from support.requirements import use_backend

    use_backend("opencl")
    cl = pytest.importorskip("pyopencl")
    from fpiwarp.backends import get_backend
    from fpiwarp.backends.opencl.prepared import JobCache

    be = get_backend("opencl")
    monkeypatch.setattr(be, "_kernels", {})
    monkeypatch.setattr(be, "_jobs", JobCache())
    monkeypatch.setenv("FPIWARP_OPENCL_BUILD_CACHE", "0")

    class FailingProgram:
        def __init__(self, *args, **kwargs):
            pass

        def build(self, *args, **kwargs):
            raise cl.RuntimeError("clBuildProgram failed: BUILD_PROGRAM_FAILURE\n\nBuild on <pyopencl.Device "
                                  "'pthread-skylake-avx512'>:\n\nerror: unknown target CPU 'generic'\n"
                                  "note: valid target CPU values are: nocona, core2")

    monkeypatch.setattr(be._cl, "Program", FailingProgram)
    fpiwarp.set_default_backend(None)
    monkeypatch.setattr(default, "ranking", lambda: ["opencl", "numpy"])
    img = image()
    got = fpiwarp.warp_image(img, F)  # falls back: no RuntimeError
    np.testing.assert_array_equal(got, fpiwarp.warp_image(img, F, backend="numpy"))
    reason = backend_status()["opencl"]
    assert reason is not None and "unknown target CPU 'generic'" in reason and "\n" not in reason
    assert default.host_backend("uint8") == "numpy"
    with pytest.raises(fpiwarp.BackendUnavailableError, match="unknown target CPU"):
        fpiwarp.warp_image(img, F, backend="opencl")


def test_an_explicit_backend_whose_build_fails_raises_a_one_line_error(monkeypatch):
    from support.requirements import use_backend

    use_backend("opencl")
    cl = pytest.importorskip("pyopencl")
    from fpiwarp.backends import get_backend
    from fpiwarp.backends.opencl.prepared import JobCache

    be = get_backend("opencl")
    saved = dict(fpiwarp.backends._failed)
    monkeypatch.setattr(be, "_kernels", {})
    monkeypatch.setattr(be, "_jobs", JobCache())
    monkeypatch.setenv("FPIWARP_OPENCL_BUILD_CACHE", "0")

    def fails(*args, **kwargs):
        raise cl.RuntimeError("clBuildProgram failed: BUILD_PROGRAM_FAILURE\n\nerror: unknown target CPU 'generic'")

    monkeypatch.setattr(be._cl.Program, "build", fails)
    try:
        with pytest.raises(fpiwarp.BackendUnavailableError) as err:
            fpiwarp.warp_image(image(), F, backend="opencl", order=3, mode="wrap")
        assert "unknown target CPU 'generic'" in str(err.value) and "\n" not in str(err.value)
        assert not isinstance(err.value, cl.Error)
    finally:
        fpiwarp.backends._failed.clear()
        fpiwarp.backends._failed.update(saved)


def test_the_probe_reports_a_compiler_that_cannot_build(monkeypatch):
    cl = pytest.importorskip("pyopencl")
    from fpiwarp.backends.opencl import backend as ocl

    try:
        ocl.choose_device()
    except RuntimeError:
        pytest.skip("no OpenCL device")

    def fails(self, *args, **kwargs):
        raise cl.RuntimeError("clBuildProgram failed: BUILD_PROGRAM_FAILURE\n\nerror: unknown target CPU 'generic'")

    monkeypatch.setattr(cl.Program, "build", fails)
    reason = ocl.probe()
    assert reason is not None and "cannot build fpiwarp's kernels (unknown target CPU 'generic')" in reason


def test_the_default_never_takes_the_gl_context_in_a_worker_thread(fresh, monkeypatch):
    gl = pytest.importorskip("fpiwarp.backends.gl")
    if gl.owner_thread() is not None and gl.owner_thread() != threading.get_ident():
        pytest.skip("the GL context belongs to another thread already")
    monkeypatch.setattr(default, "ranking", lambda: ["gl", "numpy"])
    got = {}

    def work():
        got["name"] = default.host_backend("uint8")
        got["out"] = fpiwarp.warp_image(image(), F)

    t = threading.Thread(target=work)
    t.start()
    t.join()
    owner = gl.owner_thread()
    assert owner is None or owner == threading.get_ident()
    if owner is None:
        assert got["name"] == "numpy"
    assert got["out"].shape == (31, 41, 3)


def test_warp_batch_and_warper_use_the_default(fresh):
    name = fpiwarp.default_backend()
    stack = np.stack([image(), image()[::-1].copy()])
    np.testing.assert_array_equal(fpiwarp.warp_batch(stack, F), fpiwarp.warp_batch(stack, F, backend=name))
    warper = fpiwarp.Warper(F)
    assert warper.backend == name
    np.testing.assert_array_equal(warper(stack[0]), fpiwarp.warp_image(stack[0], F, backend=name))


def test_import_never_measures_nor_probes(tmp_path):
    """Importing fpiwarp writes no measurement and imports no backend driver."""
    code = ("import sys, fpiwarp; from fpiwarp.backends import _status;"
            "print(sorted(_status), [m for m in ('pyopencl', 'warp', 'moderngl') if m in sys.modules])")
    env = {**os.environ, default.ENV_CACHE_DIR: str(tmp_path), "PYTHONPATH": str(ROOT)}
    env.pop(default.ENV_DEFAULT, None)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=ROOT, check=True)
    assert out.stdout.strip() == "[] []"
    assert not list(tmp_path.iterdir())


def test_backend_options_without_a_backend_are_refused_naming_their_backend(fresh):
    with pytest.raises(fpiwarp.ArgumentError, match=r"backend_options \['hardware_filter'\] are options of one "
                                                    r"backend \(declared by 'gl'\): name it with backend="):
        fpiwarp.warp_image(image(), F, backend_options={"hardware_filter": True})
    with pytest.raises(fpiwarp.ArgumentError, match="backend_options"):
        fpiwarp.Warper(F, backend_options={"nope": 1})
