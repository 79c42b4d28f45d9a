"""The experiment pictures people read: the demo's comparison rows, and plots whose series never share a look."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from types import SimpleNamespace

import cv2
import numpy as np
import pytest
from stamlane_eval.io import read_tusimple, tusimple_points

from stamlane.experiments.demo import _comparison, differing_frames
from stamlane.experiments.plots import SERIES_COLOURS, series_style
from stamlane.experiments.recipes import Row
from stamlane.experiments.split_scores import score_split
from stamlane.experiments.store import RunStore
from stamlane.predict.overlay import LANE_COLOURS, OKABE_ITO, draw_lanes, text_scale


def test_the_frames_where_models_differ_most_come_first() -> None:
    a = {"x.jpg": 1.0, "y.jpg": 0.9, "z.jpg": 0.5, "w.jpg": 0.7}
    b = {"x.jpg": 1.0, "y.jpg": 0.1, "z.jpg": 0.2, "w.jpg": 0.7, "only_b.jpg": 0.0}
    c = {"x.jpg": 0.9, "y.jpg": 0.5, "z.jpg": 0.5, "w.jpg": 0.4, "only_b.jpg": 1.0}
    assert differing_frames([a, b, c], 3) == ["y.jpg", "z.jpg", "w.jpg"]  # spreads 0.8, 0.3, 0.3 (by name), 0.1
    assert differing_frames([a, b, c], 10) == ["y.jpg", "z.jpg", "w.jpg", "x.jpg"]  # none some model lacks
    assert differing_frames([], 3) == []
    d = {"clips/1/5.jpg": 0.0, "clips/1/9.jpg": 0.1, "clips/2/9.jpg": 0.6, "clips/3/9.jpg": 1.0}
    e = dict.fromkeys(d, 1.0)  # spreads 1.0, 0.9, 0.4, 0.0: clip 1's second frame after the other clips' first
    assert differing_frames([d, e], 3) == ["clips/1/5.jpg", "clips/2/9.jpg", "clips/3/9.jpg"]
    assert differing_frames([d, e], 4) == ["clips/1/5.jpg", "clips/2/9.jpg", "clips/3/9.jpg", "clips/1/9.jpg"]


@pytest.fixture(scope="module")
def challenging(tiny_synthetic: Callable[..., Path]) -> Path:
    return tiny_synthetic(256, 144, 4, train=0, val=0, test=0, challenging=4)


def test_the_comparison_shows_the_frames_where_models_differ(challenging: Path, tmp_path: Path) -> None:
    """Two models equal to the labels but on two frames, where the second model finds no lane / one lane less: the
    picture holds those two frames, in that order, one column per model, and only there do the columns differ."""
    gts = read_tusimple(challenging / "challenging.json")
    worst, second = gts[2]["raw_file"], gts[0]["raw_file"]
    rows = [Row("stam4", "4 frames", ("demo.yaml",)), Row("single", "1 frame", ("demo_single.yaml",))]

    store = RunStore(tmp_path)  # the run layout, as the engine's
    for row in rows:
        folder = store.pred_dir(store.run_name(row.name, 0), "challenging")
        folder.mkdir(parents=True)
        records = []
        for gt in gts:
            lanes = gt["lanes"]
            if row.name == "single":
                lanes = [] if gt["raw_file"] == worst else lanes[1:] if gt["raw_file"] == second else lanes
            records.append({"raw_file": gt["raw_file"], "lanes": lanes, "h_samples": gt["h_samples"], "run_time": 1})
        (folder / "predictions.json").write_text("".join(json.dumps(r) + "\n" for r in records))
        score_split(folder, challenging, "challenging", 4)
    experiment = SimpleNamespace(store=store, seeds=[0], root=challenging)
    picture = cv2.imread(str(_comparison(experiment, rows, tmp_path / "comparison.jpg", count=2)))
    # layout: a header naming the models, a legend line, then per frame a line naming it and its row of cells
    scale = text_scale(np.zeros((144, 256, 3)))
    header, line = round(70 * scale), round(60 * scale)
    assert picture.shape == (header + line + 2 * (line + 144), 2 * 256, 3)

    def cells(k: int) -> tuple[np.ndarray, np.ndarray]:
        top = header + line + k * (line + 144) + line
        return picture[top : top + 144, :256], picture[top : top + 144, 256:]

    def drawn(name: str, lanes: list) -> np.ndarray:  # what a cell shows below its score line
        gt = next(g for g in gts if g["raw_file"] == name)
        points = [p for p in tusimple_points(lanes, gt["h_samples"]) if len(p) >= 2]
        truth = [p for p in tusimple_points(gt["lanes"], gt["h_samples"]) if len(p) >= 2]
        return draw_lanes(cv2.imread(str(challenging / name)), points, truth)[40:].astype(int)

    def gap(cell: np.ndarray, expected: np.ndarray) -> float:
        return float(np.abs(cell[40:].astype(int) - expected).mean())

    truth = {g["raw_file"]: g["lanes"] for g in gts}
    (a0, b0), (a1, b1) = cells(0), cells(1)
    # `worst` first: the first model's lanes, the second's none; then `second`, the second model one lane short
    both, none = drawn(worst, truth[worst]), drawn(worst, [])
    assert gap(a0, both) < gap(a0, none) - 1 and gap(b0, none) < gap(b0, both) - 1
    both, short = drawn(second, truth[second]), drawn(second, truth[second][1:])
    assert gap(a1, both) < gap(a1, short) - 1 and gap(b1, short) < gap(b1, both) - 1


def test_plot_series_never_look_alike_and_are_colour_blind_safe() -> None:
    styles = [series_style(k) for k in range(28)]
    assert len({tuple(s.values()) for s in styles}) == 28
    palette = {f"#{r:02x}{g:02x}{b:02x}" for r, g, b in OKABE_ITO.values()}
    assert {s["color"] for s in styles} <= palette and len({s["color"] for s in styles}) == len(SERIES_COLOURS)
    assert "yellow" not in SERIES_COLOURS  # faint on white
    for k in range(len(SERIES_COLOURS) - 1):  # neighbours differ in colour and marker
        assert styles[k]["color"] != styles[k + 1]["color"] and styles[k]["marker"] != styles[k + 1]["marker"]
    assert len(set(LANE_COLOURS)) == len(LANE_COLOURS)
