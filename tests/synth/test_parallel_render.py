"""The set rendered by two processes is the set rendered by one, byte for byte (`generate_dataset`'s ``workers``)."""

from __future__ import annotations

from pathlib import Path

from stamlane.synth import generate_dataset
from stamlane.synth.layout import SplitCounts
from tests.conftest import TINY_SYNTH


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_two_workers_write_the_bytes_one_writes(tmp_path: Path) -> None:
    splits = {"train": 3, "val": 1, "test": 1, "challenging": 2, "reveal": 2, "train_motion": 1, "train_factors": 1}
    one, two = tmp_path / "one", tmp_path / "two"
    generate_dataset(one, SplitCounts(**splits), seed=9, config=TINY_SYNTH, progress=False, workers=1)
    generate_dataset(two, SplitCounts(**splits), seed=9, config=TINY_SYNTH, progress=False, workers=2)
    a, b = _files(one), _files(two)
    assert sorted(a) == sorted(b) and len(a) > 50
    assert [name for name in a if a[name] != b[name]] == []
