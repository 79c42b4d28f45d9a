"""``benchmarks/traffic_seeds.py``: the traffic diagnosis over seeds, on diagnoses written by hand."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import pytest

from tests.benchmarks.scripts import benchmark_module

RESULTS = Path(__file__).resolve().parents[2] / "docs" / "results" / "traffic"
MADE_BY = re.compile(r"<!-- traffic_seeds: (.+) -->\n\n")
"""How a committed ``seeds.md`` names each of its tables: the arguments, files relative to its folder."""


@pytest.fixture(scope="module")
def bench():
    with benchmark_module("traffic_seeds") as module:
        yield module


def _diagnosis(models: dict[str, tuple[float, float, float]]) -> dict:
    """One kind's summary as ``traffic_diagnosis.py`` writes it: each checkpoint's real, copies and exact F1."""
    scored = {
        name: {h: {"f1": {"value": v, "low": v, "high": v}} for h, v in zip(("real", "copies", "exact"), f1s)}
        for name, f1s in models.items()
    }
    return {"seed": 58, "kinds": {"oncoming_close": {"summary": {"models": scored}}}}


def test_groups_are_summed_over_seeds_and_paired_seed_by_seed(bench, tmp_path: Path, capsys) -> None:
    first = {"new-s0": (0.90, 0.80, 0.95), "old-s0": (0.85, 0.85, 0.90), "shipped": (0.5, 0.5, 0.5)}
    second = {"new-s1": (0.80, 0.78, 0.85), "old-s1": (0.82, 0.81, 0.88), "new-s2": (0.84, 0.80, 0.9)}
    second["old-s2"] = (0.80, 0.80, 0.85)
    for name, models in (("a", first), ("b", second)):
        (tmp_path / f"{name}.json").write_text(json.dumps(_diagnosis(models)))
    files = [str(tmp_path / "a.json"), str(tmp_path / "b.json")]
    assert bench.main([*files, "--groups", "new", "old"]) == 0
    cells = [[c.strip() for c in row.strip("|").split("|")] for row in capsys.readouterr().out.splitlines()[2:]]
    rows = {row[1]: row for row in cells}
    assert set(rows) == {"new", "old", "new − old, paired"}, "an unseeded checkpoint is left alone"
    assert rows["new"][2:] == ["3", "84.7 ± 5.0", "79.3 ± 1.2", "90.0 ± 5.0", "+5.3 ± 4.2"]
    real, use = rows["new − old, paired"][3], rows["new − old, paired"][6]
    assert real.startswith("+2.3 [") and real.endswith("(+5.0 / -2.0 / +4.0)")  # seed by seed: 90-85, 80-82, 84-80
    low, high = (float(v) for v in real.split("[")[1].split("]")[0].split(", "))
    assert low < 0 < high, "three seeds this spread resolve nothing"
    assert use.startswith("+5.0 [") and use.endswith("(+10.0 / +1.0 / +4.0)")  # (real - copies), new - old


def test_bad_inputs_are_one_line_and_status_2(bench, tmp_path: Path, capsys) -> None:
    good = tmp_path / "good.json"
    good.write_text(json.dumps(_diagnosis({"new-s0": (0.9, 0.8, 0.9), "new-s1": (0.8, 0.8, 0.8)})))
    (tmp_path / "other.json").write_text(json.dumps(_diagnosis({"new-s1": (0.7, 0.7, 0.7)})))
    (tmp_path / "broken.json").write_text("{broken")
    (tmp_path / "list.json").write_text("[1]")
    (tmp_path / "unscored.json").write_text(json.dumps({"kinds": {"same_speed": {"summary": {}}}}))
    (tmp_path / "lone.json").write_text(json.dumps(_diagnosis({"new-s0": (0.9, 0.8, 0.9), "old-s1": (1, 1, 1)})))
    cases = {
        "not JSON": [str(tmp_path / "broken.json")],
        "not an object": [str(tmp_path / "list.json")],
        "has no models": [str(tmp_path / "unscored.json")],
        "name one of them": [str(good), str(tmp_path / "other.json")],
        "no <group>-s<seed> runs of old": [str(good), "--groups", "new", "old"],
        "share 0 seed(s)": [str(tmp_path / "lone.json"), "--groups", "new", "old"],
        "missing": [str(tmp_path / "missing.json")],
    }
    for said, argv in cases.items():
        assert bench.main(argv) == 2, said
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("traffic_seeds: error:") and said in err[0], (said, err)
    fifo = tmp_path / "fifo.json"
    os.mkfifo(fifo)
    for hostile in ("/dev/zero", str(fifo), str(tmp_path)):  # never read to the end, never hung on, not a file
        assert bench.main([hostile]) == 2, hostile
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("traffic_seeds: error:"), (hostile, err)


@pytest.mark.parametrize("seeds", sorted(p.relative_to(RESULTS).as_posix() for p in RESULTS.rglob("seeds.md")))
def test_the_committed_seed_tables_are_their_diagnoses_numbers(bench, seeds: str, capsys) -> None:
    """Each table of a committed ``seeds.md`` is what this script prints from the diagnoses its comment names."""
    path = RESULTS / seeds
    blocks = MADE_BY.split(path.read_text())[1:]  # [arguments, table, arguments, table, ...]
    assert blocks, f"{seeds} names no traffic_seeds arguments"
    for arguments, committed in zip(blocks[::2], blocks[1::2], strict=True):
        argv = [str(path.parent / a) if a.endswith(".json") else a for a in arguments.split()]
        assert bench.main(argv) == 0
        assert capsys.readouterr().out.strip() == committed.strip(), arguments
