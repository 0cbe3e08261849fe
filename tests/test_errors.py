"""One error hierarchy: every error fpiwarp raises on purpose is an
fpiwarp.FpiwarpError that keeps its standard second base, and the command
line tells such a mistake (one line) from a bug (its traceback)."""

import errno

import numpy as np
import pytest

import fpiwarp
from fpiwarp.cli import commands as cli

#: (class, the standard exception it still is)
HIERARCHY = [
    (fpiwarp.ArgumentError, ValueError),
    (fpiwarp.ArgumentTypeError, TypeError),
    (fpiwarp.SizeLimitError, ValueError),
    (fpiwarp.DeviceMismatchError, fpiwarp.ArgumentError),
    (fpiwarp.DegenerateQuadError, ValueError),
    (fpiwarp.ConstraintError, ValueError),
    (fpiwarp.BackendUnavailableError, RuntimeError),
    (fpiwarp.MissingDependencyError, ImportError),
    (fpiwarp.InverseNotConvergedError, ArithmeticError),
    (fpiwarp.ImageError, ValueError),
    (fpiwarp.OutputExistsError, FileExistsError),
    (fpiwarp.OutputIsFolderError, IsADirectoryError),
    (fpiwarp.SpecError, ValueError),
    (fpiwarp.IllConditionedPairError, fpiwarp.DegenerateQuadError),
    (fpiwarp.FoldOverError, fpiwarp.ConstraintError),
]


@pytest.mark.parametrize("cls, standard", HIERARCHY)
def test_errors_are_fpiwarp_errors_and_keep_their_standard_base(cls, standard):
    assert issubclass(cls, fpiwarp.FpiwarpError) and issubclass(cls, standard)
    assert cls.__module__ == "fpiwarp" and getattr(fpiwarp, cls.__name__) is cls


def test_every_error_class_of_errors_module_reports_as_fpiwarp():
    from fpiwarp import errors as _errors

    for name in _errors.__all__:
        cls = getattr(_errors, name)
        assert issubclass(cls, Exception) and cls.__module__ == "fpiwarp", name
        assert "fpiwarp." + name in repr(cls)


def test_canonical_output_exists_error_message():
    from fpiwarp.errors import OutputExistsError

    exc = OutputExistsError("out.png")
    assert exc.errno == errno.EEXIST and str(exc) == "out.png already exists (pass overwrite=True to replace it)"


SQ = [[0, 0], [10, 0], [10, 10], [0, 10]]


@pytest.mark.parametrize(
    "kwargs, error, phrase",
    [
        ({"edges": (0, 0)}, fpiwarp.ConstraintError, "two different edge indices"),
        ({"edges": "ab"}, fpiwarp.ConstraintError, "two edge indices"),
        ({"edges": (0, 2), "delta": -1}, fpiwarp.ConstraintError, "delta"),
        ({"edges": (0, 2), "points_per_edge": 1}, fpiwarp.ConstraintError, "points_per_edge"),
        ({"edges": (0, 2), "points_per_edge": 2.0}, fpiwarp.ArgumentTypeError, "points_per_edge"),
    ],
)
def test_constrained_fpi_raises_fpiwarp_errors(kwargs, error, phrase):
    with pytest.raises(error, match=phrase):
        fpiwarp.ConstrainedFPI(SQ, [[1, 0], [11, 1], [10, 11], [0, 10]], **kwargs)


def test_adjacent_edges_without_a_shared_similarity():
    dst = [[0, 0], [20, 0], [20, 10], [0, 10]]
    with pytest.raises(fpiwarp.ConstraintError, match="one shared similarity"):
        fpiwarp.ConstrainedFPI(SQ, dst, edges=(0, 1))


def test_a_bug_shows_its_traceback_and_says_it_is_one(monkeypatch, capsys, tmp_path):
    def broken(args):
        raise KeyError("internal")

    monkeypatch.setattr(cli, "cmd_backends", broken)
    code = cli.main(["backends"])
    err = capsys.readouterr().err
    assert code == cli.BUG_STATUS == 70
    assert "Traceback" in err and "KeyError: 'internal'" in err
    assert err.strip().splitlines()[-1].startswith("fpiwarp: internal error (KeyError): this is a bug in fpiwarp")


@pytest.mark.parametrize("exc", [ValueError("plain"), TypeError("plain"), AssertionError("plain")])
def test_plain_standard_exceptions_are_bugs_not_user_errors(monkeypatch, capsys, exc):
    def broken(args):
        raise exc

    monkeypatch.setattr(cli, "cmd_backends", broken)
    assert cli.main(["backends"]) == cli.BUG_STATUS
    assert "Traceback" in capsys.readouterr().err


@pytest.mark.parametrize(
    "exc", [fpiwarp.ArgumentError("bad\nvalue"), fpiwarp.SizeLimitError("too big"), FileNotFoundError(2, "gone", "x")]
)
def test_fpiwarp_errors_and_os_errors_are_one_line(monkeypatch, capsys, exc):
    def mistake(args):
        raise exc

    monkeypatch.setattr(cli, "cmd_backends", mistake)
    assert cli.main(["backends"]) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_warp_image_errors_are_fpiwarp_errors():
    image = np.zeros((4, 4), np.uint8)
    f = fpiwarp.FPI(SQ, SQ)
    for kwargs in ({"order": 2}, {"mode": "mirror"}, {"cval": np.nan}, {"output_shape": (0, 3)},
                   {"backend": "vulkan"}, {"image": [[1]]}, {"transform": "map"}):
        args = {"image": image, "transform": f, **kwargs}
        with pytest.raises(fpiwarp.FpiwarpError):
            fpiwarp.warp_image(args.pop("image"), args.pop("transform"), **args)


def test_the_gl_thread_refusal_and_the_line_bounds_refusal_are_fpiwarp_errors():
    """Both stay catchable as before (RuntimeError, ValueError)."""
    import numpy as np

    assert issubclass(fpiwarp.ThreadOwnershipError, fpiwarp.FpiwarpError)
    assert issubclass(fpiwarp.ThreadOwnershipError, RuntimeError)
    dart = np.array([[0, 0], [4, 0], [2, 1], [2, 3]], float)
    for construction in ("continuous", "paper"):
        try:
            fpiwarp.LocalDeformation(dart, dart, edges=(0, 2), construction=construction)
        except fpiwarp.ConstraintError as exc:
            assert isinstance(exc, ValueError) and "\n" not in str(exc)
            assert "src point 1 lies beyond the line of constrained edge 2" in str(exc)
        else:
            raise AssertionError("not refused")
