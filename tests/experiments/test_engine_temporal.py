"""The engine follows clips frame after frame: predictions of every frame of the temporal subset, each with its own
history, scored with RVLD's temporal stability per clip, and the per-clip counts in the summary's values."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest
import torch
from stamlane_eval import temporal
from stamlane_eval.io import read_tusimple, tusimple_points
from stamlane_eval.video import Frame

from stamlane.experiments.engine import Experiment
from stamlane.experiments.recipes import Recipe, Row
from stamlane.experiments.summary import Summary
from stamlane.synth.generator import FIRST_KEY, TEMPORAL_LABELS
from tests.experiments import tiny_experiments

torch.set_num_threads(1)
SHRINK = (*tiny_experiments.SHRINK, "--trainer.enable_progress_bar=false")


ROW = Row.paper_row("f2_mixed_cs_features")


@pytest.fixture(scope="module")
def followed(tiny_synthetic, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Experiment, Summary]:
    """One run of 2 steps whose challenging clips are followed frame after frame, with its history probed (the
    data root, the experiment and its summary): both tests of the module read it."""
    root = tiny_synthetic(128, 72, FIRST_KEY + 3, train=2, val=1, test=2, challenging=8)  # 3 frames with history
    out = tmp_path_factory.mktemp("temporal") / "out"
    experiment = Experiment([ROW], Recipe("paper", steps=2), [0], root, out, extra=SHRINK, max_overlays=0)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(sys, "argv", ["stamlane"])  # LightningCLI warns when given args while it holds pytest's own
        return root, experiment, experiment.run([])


def test_clips_followed_frame_after_frame(followed: tuple[Path, Experiment, Summary]) -> None:
    root, experiment, summary = followed
    row = ROW
    labels = [json.loads(line) for line in (root / TEMPORAL_LABELS).read_text().splitlines()]
    assert len(labels) == 8 * 3  # one clip per factor, frames 8, 9 and 10
    run = summary.model(row.name).runs[0]
    frames = experiment.temporal_split()
    assert run.scores[frames]["clips"] == 8 and run.scores[frames]["frames"] == 24
    # the counts are RVLD's on the run's own predictions, grouped by clip in time order
    preds = {
        p["raw_file"]: p for p in read_tusimple(experiment.pred_dir(f"{row.name}-s0", frames) / "predictions.json")
    }
    sequences: dict[str, list[Frame]] = {}
    for gt in labels:
        pred = preds[gt["raw_file"]]
        sequences.setdefault(gt["raw_file"].rsplit("/", 1)[0], []).append(
            Frame(tusimple_points(pred["lanes"], gt["h_samples"]), tusimple_points(gt["lanes"], gt["h_samples"]))
        )
    expected = temporal.evaluate(sequences, (0.5, 0.8), (72, 128)).totals[0.5]
    assert expected.total > 0  # annotated lanes matched between frames are counted whatever was predicted
    for key, want in (("temporal_rs@0.5", expected.rs), ("temporal_rm@0.5", expected.rm)):
        value = summary.value(row.name, key, frames)
        assert value.mean == pytest.approx(want, abs=1e-12) and value.images == 8
    rows = [
        json.loads(line)
        for line in (experiment.pred_dir(f"{row.name}-s0", frames) / "per_clip.jsonl").read_text().splitlines()
    ]
    assert [r["frames"] for r in rows] == [3] * 8 and sum(r["temporal"]["0.5"][0] for r in rows) == expected.ns


def test_frame_after_frame_with_the_key_frame_copied_into_the_history(
    followed: tuple[Path, Experiment, Summary],
) -> None:
    """History use of temporal stability: the clips followed again with the key frame in every history slot (not
    with another clip's history, which would be one clip's for every frame), compared with the real history."""
    from stamlane.experiments.tables import tables

    _, experiment, summary = followed
    row = ROW
    frames = experiment.temporal_split()
    scores = summary.model(row.name).runs[0].scores
    assert scores[f"{frames}@key"]["clips"] == 8 and f"{frames}@other_clip" not in scores
    assert (experiment.pred_dir(f"{row.name}-s0", frames, "key") / "predictions.json").is_file()
    real, copied = (summary.value(n, "temporal_rs@0.5", frames) for n in (row.name, f"{row.name}@key"))
    use = summary.difference(row.name, f"{row.name}@key", frames, "temporal_rs@0.5")
    assert use.kind == "history_key" and use.diff == pytest.approx(real.mean - copied.mean, abs=1e-9)
    assert f"{row.name} − {row.name}@key" in tables(summary)
