"""The committed results of each kind of machine stay apart: every table in
``benchmarks/results/<kind>/`` names a machine of that kind (its ISA, and
its PoCL device where PoCL ran), so figures of an AVX2 and an AVX-512 machine
are never read as one run's."""

import json
from pathlib import Path

import pytest

RESULTS = Path(__file__).resolve().parents[2] / "benchmarks" / "results"
#: Each ISA's PoCL device.
DEVICES = {"AVX2": "pthread-haswell", "AVX-512": "pthread-skylake-avx512"}
#: Each kind's folder and the ISA its machine lines name.
KINDS = {"avx2": "AVX2"}


def _tables(kind):
    return sorted((RESULTS / kind).glob("*.md"))


def test_each_kind_folder_holds_tables():
    for kind in KINDS:
        assert _tables(kind), f"benchmarks/results/{kind}/ has no tables"


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_every_table_in_a_kind_folder_names_that_kind(kind):
    isa = KINDS[kind]
    device, others = DEVICES[isa], [d for i, d in DEVICES.items() if i != isa]
    for path in _tables(kind):
        text = path.read_text(encoding="utf-8")
        named = f"({isa})" in text or f"ISA: {isa.lower()}" in text
        assert named, f"{path.name}: no machine line naming {isa}"
        if "PoCL device" in text or "pthread-" in text:
            assert device in text, f"{path.name}: PoCL device is not {device}"
        assert not any(d in text for d in others), f"{path.name}: names another kind's PoCL device"
        companion = path.with_suffix(".json")
        if companion.exists() and isa != "AVX-512":
            recorded = json.dumps(json.loads(companion.read_text(encoding="utf-8"))).lower()
            assert "avx512f" not in recorded, f"{companion.name}: records an AVX-512 CPU"
