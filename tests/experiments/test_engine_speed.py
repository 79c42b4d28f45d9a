"""What the engine leaves out to keep README command 1 within its time, and why it changes no number: another
clip's history probed on the reveal splits only (``--all-probes``: everywhere), the matched null of a run that
does not align scored as its key-copied probe (the same input), the curves' validations on fewer batches (the same
final weights)."""

from __future__ import annotations

import csv
from dataclasses import replace
from pathlib import Path

import pytest
import torch

from stamlane.experiments.engine import ALL_PROBES, REVEAL_PROBES, SPLIT_PROBES, Experiment
from stamlane.experiments.recipes import Recipe, Row
from stamlane.experiments.runner import predicted_as
from stamlane.training.run_record import RunRecord

torch.set_num_threads(1)
SHRINK = (
    "--data.clip.image_size=[32, 64]",
    "--data.loader.batch_size=2",
    "--data.loader.num_workers=0",
    "--model.encoder.width=0.125",
    "--model.channels_last=false",
    "--trainer.enable_progress_bar=false",
)


def _run_folder(tmp_path: Path, align: str) -> RunRecord:
    run = tmp_path / f"run-{align}"
    run.mkdir()
    (run / "config.yaml").write_text(f"data:\n  clip:\n    align: {align}\n")
    (run / "checkpoints").mkdir()  # a finished run (opened through the gate, which reads only its config here)
    (run / "checkpoints" / "last.ckpt").touch()
    return RunRecord(run, run / "checkpoints" / "last.ckpt", frames=4, seed=0, train_minutes=0.0)


def test_which_probes_each_split_gets(tmp_path: Path) -> None:
    experiment = Experiment([], Recipe("paper", steps=1), [0], tmp_path, tmp_path / "out")
    aligned, unaligned = _run_folder(tmp_path, "fly"), _run_folder(tmp_path, "none")
    assert SPLIT_PROBES == ("key",) and ALL_PROBES == ("key", "other_clip")
    assert experiment.probes_of("test", aligned) == SPLIT_PROBES == experiment.probes_of("challenging", unaligned)
    assert experiment.probes_of("reveal", aligned) == REVEAL_PROBES
    assert experiment.probes_of("reveal-traffic", unaligned) == tuple(p for p in REVEAL_PROBES if p != "exact")
    assert experiment.probes_of("test", replace(aligned, frames=1)) == ()  # a single frame has no history
    everywhere = Experiment([], Recipe("paper", steps=1), [0], tmp_path, tmp_path / "out", all_probes=True)
    assert everywhere.probes_of("challenging", aligned) == ALL_PROBES
    # the matched null of a run that does not align is the key copied: predicted once, under the key's name
    assert predicted_as(unaligned, "warped_key") == "key"
    assert predicted_as(aligned, "warped_key") == "warped_key"
    assert predicted_as(unaligned, "reversed") == "reversed"


@pytest.mark.usefixtures("plain_argv")
def test_the_matched_null_of_an_unaligned_run_is_its_key_copied(tiny_synthetic, tmp_path: Path) -> None:
    root = tiny_synthetic(128, 72, 12, train=2, val=1, test=1, challenging=0, reveal=3, reveal_traffic=2)
    row = Row.paper_row("f2_noalign_mixed_cs_features")
    experiment = Experiment(
        [row],
        Recipe("paper", steps=2),
        [0],
        root,
        tmp_path / "out",
        splits=("test",),
        temporal=False,
        extra=SHRINK,
        max_overlays=0,
    )
    summary = experiment.run([])
    scores = summary.model(row.name).runs[0].scores
    for split in ("reveal", "reveal-traffic"):
        assert scores[f"{split}@warped_key"] == scores[f"{split}@key"] and f"{split}@exact" not in scores
        assert not experiment.pred_dir(f"{row.name}-s0", split, "warped_key").exists()  # never predicted
        null = summary.difference(row.name, f"{row.name}@warped_key", split, "tusimple_f1")
        copied = summary.difference(row.name, f"{row.name}@key", split, "tusimple_f1")
        assert null is not None and null.diff == copied.diff and null.ci95 == copied.ci95
    assert "test@other_clip" not in scores and "reveal@other_clip" in scores


@pytest.mark.usefixtures("plain_argv")
def test_validating_on_fewer_batches_leaves_the_final_weights_bit_for_bit(tiny_synthetic, tmp_path: Path) -> None:
    root = tiny_synthetic(128, 72, 4, train=4, val=4, test=0, challenging=0)  # 2 validation batches of 2
    row = Row.paper_row("f2_mixed_cs_features")
    weights = []
    for batches in (None, 1):
        recipe = Recipe("paper", steps=6, val_checks=3, val_batches=batches)
        experiment = Experiment([row], recipe, [0], root, tmp_path / f"out{batches}", extra=SHRINK)
        run = experiment.runner.train(row, 0, recipe.training(row), experiment.settings()).run
        weights.append(torch.load(run / "checkpoints" / "last.ckpt", weights_only=True)["state_dict"])
        with (run / "metrics.csv").open() as f:
            validated = [r for r in csv.DictReader(f) if r.get("val/tusimple_f1")]
        assert len(validated) == 3  # the curves are still drawn
    assert weights[0].keys() == weights[1].keys()
    assert all(torch.equal(weights[0][k], weights[1][k]) for k in weights[0])
