"""The backend registry: status, reasons, and clear errors."""

import pytest

import fpiwarp
from fpiwarp import BackendUnavailableError, RLinear, backends


def test_status_lists_every_backend_with_a_reason_or_none():
    status = fpiwarp.backend_status()
    assert set(status) == {"numpy", "opencl", "warp", "gl"}
    assert status["numpy"] is None
    for reason in status.values():
        assert reason is None or (isinstance(reason, str) and reason)
    assert "numpy" in fpiwarp.available_backends()


def test_unavailable_backend_names_the_extra(monkeypatch):
    monkeypatch.setitem(backends._status, "opencl", (None, "no OpenCL platform found"))
    with pytest.raises(BackendUnavailableError, match=r"no OpenCL platform found.*pip install 'fpiwarp\[opencl\]'"):
        fpiwarp.map_points(RLinear(1), [[0.0, 0.0]], backend="opencl")


def test_unknown_backend():
    with pytest.raises(ValueError, match="unknown backend 'cuda'.*numpy"):
        backends.get_backend("cuda")


def test_a_crashing_probe_becomes_a_reason(monkeypatch):
    class Broken:
        @staticmethod
        def probe():
            raise OSError("libOpenCL.so: cannot open shared object file")

    monkeypatch.setattr(backends.importlib, "import_module", lambda name: Broken)
    module, reason = backends._probe("opencl")
    assert "OSError" in reason and "libOpenCL" in reason
