"""benchmarks/common.py: the helpers every benchmark shares (machine facts,
rounds of timings, tables, inputs). No timing is asserted, only what the
helpers promise: who is called when, what a table and a description hold."""

import sys

import numpy as np
from support import ROOT

sys.path.insert(0, str(ROOT))  # benchmarks/ lives beside the package, not in it

from benchmarks import common  # noqa: E402 (needs the path above)


def test_interleaved_calls_each_implementation_once_per_round_after_a_warm_up():
    order = []
    calls = {"a": lambda: order.append("a") or 1, "b": lambda: order.append("b") or 2}
    times, results = common.interleaved(calls, 3)
    assert order == ["a", "b"] * 4  # warm-up round, then 3 timed rounds
    assert {k: len(v) for k, v in times.items()} == {"a": 3, "b": 3}
    assert results == {"a": 1, "b": 2}
    assert all(t >= 0 for ts in times.values() for t in ts)
    assert common.bests({"x": [3.0, 1.0, 2.0]}) == {"x": 1.0}
    assert common.medians({"x": [3.0, 1.0, 2.0]}) == {"x": 2.0}


def test_time_call_keeps_to_its_repeats():
    calls = []
    best, times = common.time_call(lambda: calls.append(1), budget_s=0.0, max_repeats=5, min_repeats=2)
    assert len(times) == 2 and len(calls) == 3 and best == min(times)


def test_machine_facts_name_cpu_isa_and_pocl_device():
    facts = common.machine_facts(backends=False)
    assert facts["cpu"] and facts["isa"] and facts["pocl_device"]
    assert "backends" not in facts
    line = common.machine_line(facts)
    assert facts["cpu"] in line and facts["isa"] in line and facts["pocl_device"] in line
    md = common.machine_markdown(facts)
    assert f"{facts['cpu']} ({facts['isa']}), PoCL device {facts['pocl_device']}" in md


def test_isa_is_read_from_the_cpu_flags(monkeypatch):
    for flags, isa in [("fpu sse4_2 avx avx2 avx512f", "AVX-512"), ("fpu sse4_2 avx avx2", "AVX2"),
                       ("fpu sse4_2", "SSE4.2")]:
        monkeypatch.setattr(common, "_cpuinfo", lambda flags=flags: f"model name\t: X\nflags\t\t: {flags}\n")
        assert common.cpu_isa() == isa


def test_tables_and_labels():
    table = common.markdown_table(["impl", "ms"], [["a", 1.5], ["b", 2]])
    assert table.splitlines() == ["| impl | ms |", "|---|---:|", "| a | 1.5 |", "| b | 2 |"]
    assert common.fmt_time(2e-6) == "2 µs" and common.fmt_time(0.0123) == "12.3 ms" and common.fmt_time(None) == "–"
    assert common.fmt_ratio(0.5) == "0.50×" and common.fmt_ratio(14.2) == "14×"
    assert common.size_label("1080x1920") == "1920×1080" and common.size_label("10000000") == "10M pts"


def test_inputs_are_seeded_and_shaped():
    a = common.test_image(20, 30, "uint8", np.random.default_rng(0))
    b = common.test_image(20, 30, "uint8", np.random.default_rng(0))
    assert a.shape == (20, 30, 3) and a.dtype == np.uint8 and np.array_equal(a, b)
    assert common.test_image(8, 8, "float32", np.random.default_rng(0), channels=4).shape == (8, 8, 4)
    f = common.frame_fpi(40, 64)
    src = np.array([[0, 0], [63, 0], [63, 39], [0, 39]], dtype=float)
    assert np.allclose(f(src), [[4, 3], [60, -2], [67, 42], [-3, 36]])
    maps = common.random_frame_maps(3, 40, 64, seed=1)
    assert len(maps) == 3 and not np.allclose(maps[0](src), maps[1](src))


def test_files_are_written_whole(tmp_path):
    common.write_json(tmp_path / "x.json", {"a": 1})
    assert (tmp_path / "x.json").read_text() == '{\n "a": 1\n}\n'
    assert not list(tmp_path.glob("*.tmp"))
