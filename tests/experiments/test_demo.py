"""``stamlane demo`` and the experiment engine under it: a quick run end to end, the summary's numbers against
the per-image files, history probes and oracles, resuming, the settings lock, tampered folders, rescoring."""

from __future__ import annotations

import json
import sys
from functools import partial
from pathlib import Path

import cv2
import pytest
import torch
from stamlane_eval.stats import seed_interval
from stamlane_eval.tusimple import paper_f1

from stamlane.cli import main
from stamlane.experiments.demo import pairs
from stamlane.experiments.recipes import KEY_CORRUPTION, Row
from stamlane.experiments.split_scores import SCORING, read_per_image, score_split
from stamlane.experiments.store import file_sha256
from stamlane.experiments.summary import DIFFERENCE_KINDS, Summary
from stamlane.predict.image_score import iou_width
from stamlane.synth.generator import FACTORS, REVEAL, REVEAL_TRAFFIC
from stamlane.training.runs import flags_of

torch.set_num_threads(1)
REPO = Path(__file__).resolve().parents[2]
VIEWS = ["test", "challenging", *(f"challenging:{f}" for f in FACTORS)]
VIEWS += [
    "reveal",
    "reveal-traffic",
    *(f"reveal:{k}" for k in REVEAL),
    *(f"reveal-traffic:{k}" for k in REVEAL_TRAFFIC),
]


QUICK_EXTRA = "--trainer.log_every_n_steps=1"
"""The ``stamlane fit`` argument the module's quick demo gives every run after ``--`` (a call on its folder without
it has other settings)."""


@pytest.fixture(scope="module")
def quick(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One quick demo (seed 0), with a ``stamlane fit`` argument for every run after ``--``: its output folder.
    Tests may run ``stamlane demo`` on it again, but leave it as they found it."""
    out = tmp_path_factory.mktemp("demo") / "demo"
    assert main(["demo", "--quick", "--out", str(out), "--", QUICK_EXTRA]) == 0
    return out


def test_quick_demo_writes_a_summary_that_its_files_account_for(quick: Path) -> None:
    summary = Summary.read(quick / "summary.json")
    assert [m.name for m in summary.models] == ["stam4", "single"]  # --quick leaves the no-alignment model out
    assert [m.frames for m in summary.models] == [4, 1] and summary.seeds == [0]
    assert summary.recipe == {
        "name": "cpu",
        "pretrain_steps": 3,
        "steps": 2,
        "row_args": flags_of(KEY_CORRUPTION),
        "pretrain_args": [],
    }
    assert (
        set(summary.splits_sha256) == {"test", "challenging", "reveal", "reveal-traffic"} and summary.iou_width == 5
    )  # 30 px at 256 of 1640
    # stage 2 starts from the final weights of stage 1
    ckpt = quick / "pretrain-s0" / "run" / "checkpoints" / "last.ckpt"
    assert f"init_weights: {ckpt}" in (quick / "stam4-s0" / "run" / "config.yaml").read_text()
    # what followed ``--`` reached every run's fit (the demo's trainer logs every 25 steps) and its record
    for run in ("pretrain-s0", "stam4-s0", "single-s0"):
        assert "log_every_n_steps: 1\n" in (quick / run / "run" / "config.yaml").read_text()
        assert json.loads((quick / run / "done.json").read_text())["extra"] == ["--trainer.log_every_n_steps=1"]
    # the recipe corrupts the key frames of stage 2 only, the single frame's as the others'
    assert "key_corruption: 0.0" in (quick / "pretrain-s0" / "run" / "config.yaml").read_text()
    for name in ("stam4", "single"):
        assert "key_corruption: 0.5" in (quick / f"{name}-s0" / "run" / "config.yaml").read_text()
    for model in summary.models:
        (run,) = model.runs
        assert Path(run.last_ckpt).is_file()
        for split, images in (("test", 2), ("challenging", 2 * len(FACTORS))):
            pred = quick / "predictions" / f"{model.name}-s0" / split
            assert len((pred / "predictions.json").read_text().splitlines()) == images
            assert len(list((pred / "overlays").rglob("*.jpg"))) == min(images, 12)
            rows = [json.loads(line) for line in (pred / "per_image.jsonl").read_text().splitlines()]
            assert [r["clip"] for r in rows] == [f"clips/{split}-{i:04d}" for i in range(images)]
            fp, fn = (sum(r[k] for r in rows) / images for k in ("fp", "fn"))
            assert run.scores[split]["f1"] == pytest.approx(paper_f1(fp, fn))  # the paper's F1 of those rates
            value = summary.value(model.name, "tusimple_f1", split)
            assert value.mean == pytest.approx(run.scores[split]["f1"]) and value.std is None
            assert value.ci95[0] <= value.mean + 1e-9 <= value.ci95[1] + 2e-9
            for t in ("0.5", "0.3"):  # one seed: the IoU F1 of the split is the run's own total
                iou = summary.value(model.name, f"culane_f1@{t}", split).mean
                assert iou == pytest.approx(run.scores[split][f"culane_f1@{t}"], abs=1e-12)
        # per factor: the F1 of the factor's two clips (clip i has factor i % 8), from the same rates
        rows = [
            json.loads(line)
            for line in (quick / "predictions" / f"{model.name}-s0" / "challenging" / "per_image.jsonl")
            .read_text()
            .splitlines()
        ]
        for k, factor in enumerate(FACTORS):
            fp, fn = ((rows[k][key] + rows[k + len(FACTORS)][key]) / 2 for key in ("fp", "fn"))
            found = summary.value(model.name, "tusimple_f1", f"challenging:{factor}")
            assert found.images == 2 and found.mean == pytest.approx(paper_f1(fp, fn))
    assert {(d.a, d.b) for d in summary.differences if d.kind == "models"} == {("stam4", "single")}
    views = {d.view for d in summary.differences if d.kind == "models" and d.metric == "tusimple_f1"}
    assert views == set(VIEWS)
    for name in ("val_f1.png", "history_use.png", "history_use_vs_headroom.png", "comparison.jpg"):
        picture = cv2.imread(str(quick / name))
        assert picture is not None and picture.std() > 10, name
    comparison = cv2.imread(str(quick / "comparison.jpg"))  # 3 key frames x 2 models, under labels
    assert comparison.shape[1] == 2 * 256 and 3 * 144 < comparison.shape[0] < 3 * 144 + 200
    table = (quick / "tables.md").read_text()
    assert "| 1 frame (baseline) | 1 |" in table and "History use" in table and "headroom" in table


def test_multi_frame_runs_are_scored_with_their_history_probed(quick: Path) -> None:
    summary = Summary.read(quick / "summary.json")
    stam4, single = summary.model("stam4"), summary.model("single")
    assert set(stam4.probes) == {"key", "warped_key", "reversed", "other_clip", "exact"} and not single.probes
    assert not (quick / "predictions" / "stam4-s0" / "challenging@reversed").exists()  # the reveal splits only
    assert stam4.runs[0].scores["reveal@warped_key"]["images"] == 2 * len(REVEAL)
    key_copied = summary.difference("stam4@key", "single", "reveal", "tusimple_f1")  # the training, history aside
    assert key_copied is not None and key_copied.kind == "key_copied"
    pred = quick / "predictions" / "stam4-s0" / "challenging@key"
    assert (pred / "per_image.jsonl").is_file() and not list(pred.rglob("*.jpg"))  # no overlays for probes
    assert stam4.runs[0].scores["challenging@key"]["images"] == 2 * len(FACTORS)
    # another clip's history on the reveal splits only (--all-probes: everywhere)
    assert "challenging@other_clip" not in stam4.runs[0].scores and "reveal@other_clip" in stam4.runs[0].scores
    for kind, a, b, split in (
        ("history_key", "stam4", "stam4@key", "challenging"),
        ("history_other", "stam4", "stam4@other_clip", "reveal"),
        ("history_key_exact", "stam4@exact", "stam4@key", "reveal"),  # history use with exact alignment
    ):
        found = {(d.view, d.metric) for d in summary.differences if d.kind == kind}
        assert (split, "tusimple_f1") in found and (split, "culane_f1@0.5") in found
        d = summary.difference(a, b, split, "tusimple_f1")
        real, probed = summary.value(a, "tusimple_f1", split), summary.value(b, "tusimple_f1", split)
        assert d.diff == pytest.approx(real.mean - probed.mean, abs=1e-12)
    assert {d.kind for d in summary.differences} <= set(DIFFERENCE_KINDS)
    assert "| exact − ORB alignment | exact − key copied |" in (quick / "tables.md").read_text()
    # the oracles of the labels: the quick set has visibility masks, so every view has a headroom
    assert {"oracle:key", "oracle:history-4f", "oracle:unaligned-4f", "oracle:history-8f"} <= set(summary.oracles)
    assert "oracle:history-8f-x2" not in summary.oracles  # 14 frames back: beyond every split's masks (7, 11)
    assert summary.value("oracle:history-4f-x2", "tusimple_f1", "reveal") is not None
    alignment = {d.view for d in summary.differences if d.kind == "alignment_oracle"}
    assert {"reveal", "reveal:key_spray"} <= alignment
    headroom = {d.view for d in summary.differences if d.kind == "headroom" and d.metric == "tusimple_f1"}
    assert headroom == set(VIEWS) - {"test"} or headroom == set(VIEWS)
    # recall per visibility class: the visible points of every scored split
    assert summary.value("single", "recall_visible", "challenging") is not None


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--pretrain-steps", "0"], "--pretrain-steps must be >= 1, got 0"),
        (["--finetune-steps", "-1"], "--finetune-steps must be >= 1, got -1"),
        (["--data", __file__], "is not a folder"),
        (["--seeds", "0"], "--seeds must be >= 1, got 0"),
        (["--rows", "f4_nope"], "no paper row 'f4_nope'; known rows: f1_cbam"),
        (["--quick", "--out", __file__], "is a file, not a folder"),
        (["--splits", "challenging-frames"], "--splits must name a split besides challenging-frames"),
        (["--quick", "--splits", "test", "nope"], "has no nope.json"),
        (["--reveal-probes", "key", "future"], "argument --reveal-probes: invalid choice: 'future'"),
        (["--", "--trainer.nope=1"], "the stamlane fit arguments after --: "),  # before any data are made
        (["--quick", "--", "--trainer.max_steps=many"], "the stamlane fit arguments after --: "),
    ],
)
def test_demo_bad_input(argv: list[str], message: str, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    assert main(["demo", "--out", str(tmp_path), *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1 and "Traceback" not in err
    if "--" in argv:  # fit arguments are checked before the quick set is made
        assert not list(tmp_path.iterdir())


def test_a_data_link_to_nothing_is_refused_before_anything_is_made(tmp_path: Path, capsys) -> None:
    (tmp_path / "data").symlink_to(tmp_path / "nothing-here")
    assert main(["demo", "--quick", "--data", str(tmp_path / "data"), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert "is a link to nothing" in err and len(err.splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["data"]  # neither --out nor the link's target made


def test_a_tampered_run_folder_is_refused_in_one_line(quick: Path, capsys: pytest.CaptureFixture) -> None:
    """The module's quick demo, tampered with and given back as it was (the last call rewrites its summary)."""
    out, again = quick, ["demo", "--quick", "--out", str(quick), "--", QUICK_EXTRA]
    done = out / "single-s0" / "done.json"
    config = out / "single-s0" / "run" / "config.yaml"
    record = json.loads(done.read_text())
    ckpt = Path(record["last_ckpt"])
    kept = {path: path.read_bytes() for path in (done, config, ckpt, out / "summary.json")}
    try:
        _tamper(out, again, done, config, record, capsys)
    finally:
        for path, content in kept.items():
            path.write_bytes(content)


def _tamper(out: Path, again: list[str], done: Path, config: Path, record: dict, capsys: pytest.CaptureFixture) -> None:
    cases = [
        ("{not json", "is not a run record"),
        (json.dumps(record | {"run": "/etc"}), "is not a path inside"),
        (json.dumps(record | {"last_ckpt_sha256": "0" * 64}), "changed since the run finished"),
        (json.dumps([1, 2]), "is not a run record"),
        (json.dumps(record | {"frames": None}), "frames must be int >= 1, got None"),
        (json.dumps(record | {"scores": [1]}), "scores must be dict"),
    ]
    for text, message in cases:
        done.write_text(text)
        capsys.readouterr()
        assert main(again) == 2
        err = capsys.readouterr().err.strip()
        assert message in err and len(err.splitlines()) == 1 and "Traceback" not in err
    done.write_text(json.dumps(record))
    original = config.read_text()
    config.write_text(original.replace("class_path: torch.optim.AdamW", "class_path: os.system", 1))
    capsys.readouterr()
    assert main(again) == 2  # a run folder's config may not import anything
    err = capsys.readouterr().err.strip()
    assert "names 'os.system'" in err and len(err.splitlines()) == 1
    config.write_text(
        original.replace("class_path: stamlane.models.", "class_path: stamlane.experiments.demo.os.system  #", 1)
    )
    capsys.readouterr()
    assert main(again) == 2  # a stamlane. prefix reaching the shell: not in the table
    err = capsys.readouterr().err.strip()
    assert "names 'stamlane.experiments.demo.os.system'" in err and len(err.splitlines()) == 1
    config.write_text(original)
    ckpt = Path(record["last_ckpt"])  # a checkpoint weights_only refuses, its digest forged, predicted again
    kept = ckpt.read_bytes()
    torch.save({"state_dict": {}, "x": partial(print)}, ckpt)
    done.write_text(json.dumps(record | {"last_ckpt_sha256": file_sha256(ckpt), "scores": {}}))
    capsys.readouterr()
    assert main(again) == 2
    err = capsys.readouterr().err.strip()
    assert "not a readable torch checkpoint" in err and len(err.splitlines()) == 1, err
    ckpt.write_bytes(kept)
    done.write_text(json.dumps(record))
    (out / "summary.json").write_text("{tampered")
    assert main(again) == 0  # the summary is rewritten from the runs


def test_a_demo_folder_run_again_is_reused_rescored_and_grown(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """One ``--out`` over the calls a user makes on it, in order (each step made a quick demo of its own before; one
    quick set and one stage 1 serve them all now, and the calls after the first ask for the key probe alone): the
    reveal splits with fewer probes and the paper tables on them, a second seed and other settings refused, a split's
    labels changed with paper rows added, and a model added."""
    out = tmp_path / "demo"
    _paper_tables_on_reveal_score_only_the_splits_and_probes_asked_for(out, capsys)
    _demo_reuses_finished_runs_and_refuses_other_settings(out, capsys)
    _demo_scores_a_finished_run_again_when_a_split_changes(out, capsys)
    _single_clean_is_the_single_frame_trained_without_the_key_frame_corruption(out)


FEWER = ("--splits", "test", "challenging", "--reveal-probes", "key")
"""The splits and probes of the calls after the first: the checks need no more (seeds, labels and models change)."""


def _paper_tables_on_reveal_score_only_the_splits_and_probes_asked_for(
    out: Path, capsys: pytest.CaptureFixture
) -> None:
    assert main(["demo", "--quick", "--splits", "test", "--reveal-probes", "key", "--out", str(out)]) == 0
    summary = Summary.read(out / "summary.json")
    assert set(summary.splits_sha256) == {"test", "reveal", "reveal-traffic"}  # the reveal splits always
    stam4 = summary.model("stam4")
    assert set(stam4.probes) == {"key"} and set(stam4.runs[0].scores) == {
        f"{split}{probe}" for split in ("test", "reveal", "reveal-traffic") for probe in ("", "@key")
    }
    assert not (out / "predictions" / "stam4-s0" / "challenging").exists()
    assert not (out / "predictions" / "stam4-s0" / "challenging-frames").exists()  # no frame-after-frame scoring
    # the runs are reused with every probe: the summary holds what the call asked for, no more
    assert main(["demo", "--quick", "--splits", "test", "--out", str(out)]) == 0
    summary = Summary.read(out / "summary.json")
    assert set(summary.model("stam4").probes) == {"key", "warped_key", "reversed", "other_clip", "exact"}
    assert main(["demo", "--quick", "--splits", "test", "--reveal-probes", "key", "--out", str(out)]) == 0
    summary = Summary.read(out / "summary.json")
    assert set(summary.model("stam4").probes) == {"key"}
    assert not any(d.kind == "history_reversed" for d in summary.differences)
    # Table 1 with the reveal splits as its columns, history use beside each row
    capsys.readouterr()
    report = ["report", str(out / "summary.json"), "--paper", "--tables", "1", "--splits", "reveal", "reveal-traffic"]
    assert main(report) == 0
    table = capsys.readouterr().out.splitlines()
    assert table[2].startswith("| row | paper F1 | reveal | reveal-traffic | − 1 frame (reveal / reveal-traffic) |")
    stam = next(line for line in table if "`f4_mixed_cs_features`" in line)
    cells = [c.strip() for c in stam.strip("|").split("|")]
    assert len(cells) == len(table[2].strip("|").split("|")) and cells[-1].count(" / ") == 1 and "[" in cells[-1]
    value = summary.value("stam4", "tusimple_f1", "reveal")
    assert cells[2].startswith(f"{100 * value.mean:.1f}")
    not_run = next(line for line in table if "`f2_mixed_cs_features`" in line)
    assert "| not run |" in not_run and not_run.count("|") == table[2].count("|")


def _demo_reuses_finished_runs_and_refuses_other_settings(out: Path, capsys: pytest.CaptureFixture) -> None:
    first = json.loads((out / "stam4-s0" / "done.json").read_text())
    capsys.readouterr()
    assert main(["demo", "--quick", "--seeds", "2", *FEWER, "--out", str(out)]) == 0  # seed 0 reused, seed 1 trained
    printed = capsys.readouterr().out
    assert "seed 0, stage 1: 1 frame, stage 1 (every model starts here), done before, reused" in printed
    assert "seed 1, stage 1: 1 frame, stage 1 (every model starts here), 3 steps" in printed
    again = json.loads((out / "stam4-s0" / "done.json").read_text())
    trained = ("last_ckpt_sha256", "train_minutes")
    assert {k: again[k] for k in trained} == {k: first[k] for k in trained}  # not retrained
    assert all(again["scores"][k] == v for k, v in first["scores"].items())  # challenging scored besides
    summary = Summary.read(out / "summary.json")
    runs = {m.name: m.runs for m in summary.models}
    assert [r.seed for r in runs["stam4"]] == [0, 1] and runs["stam4"][0].scores["test"] == first["scores"]["test"]
    assert summary.value("stam4", "tusimple_f1", "test").std is not None  # two seeds: a spread
    # the difference per seed is that of the two runs' own scores; its interval the t interval over seeds
    diff = summary.difference("stam4", "single", "test", "tusimple_f1")
    f1 = {(m, r.seed): r.scores["test"]["f1"] for m in ("stam4", "single") for r in runs[m]}
    assert diff.seed_diffs == pytest.approx([f1["stam4", s] - f1["single", s] for s in (0, 1)], abs=1e-12)
    assert diff.seed_ci95 == pytest.approx(list(seed_interval(diff.seed_diffs).interval), abs=1e-12)
    use = summary.difference("stam4", "stam4@key", "test", "tusimple_f1")
    assert len(use.seed_diffs) == 2 and use.seed_ci95 is not None  # history use has its interval over seeds too
    # the same folder with another budget or precision: one line, exit 2, nothing overwritten
    others = (["--data", str(out / "quick_data"), "--finetune-steps", "7"], ["--quick", "--bf16", "true"])
    for other in (*others, ["--quick", "--", "--trainer.accelerator=cpu"]):
        assert main(["demo", "--out", str(out), *other]) == 2
        err = capsys.readouterr().err.strip()
        assert "was made with other settings" in err and len(err.splitlines()) == 1
    assert json.loads((out / "stam4-s0" / "done.json").read_text()) == again


def _demo_scores_a_finished_run_again_when_a_split_changes(out: Path, capsys: pytest.CaptureFixture) -> None:
    first = json.loads((out / "single-s0" / "done.json").read_text())
    labels = out / "quick_data" / "challenging.json"
    labels.write_text("".join(line + "\n" for line in labels.read_text().splitlines()[: len(FACTORS)]))
    # a run scored under older rules is scored again from its predictions, not predicted again
    done = out / "stam4-s0" / "done.json"
    before = json.loads(done.read_text())
    done.write_text(json.dumps(before | {"scoring": "no-time-limit"}))
    preds = out / "predictions" / "stam4-s0" / "test" / "predictions.json"
    records = [json.loads(line) for line in preds.read_text().splitlines()]
    records[0]["run_time"] = 500.0  # a busy machine: counted as late, still scored
    preds.write_text("".join(json.dumps(r) + "\n" for r in records))
    capsys.readouterr()
    # and rows of the tables: f4_add is trained, f4_mixed_cs_features IS the demo's stam4 and is not trained again
    assert main(["demo", "--quick", *FEWER, "--out", str(out), "--rows", "f4_add", "f4_mixed_cs_features"]) == 0
    printed = capsys.readouterr().out
    assert "single-s0: the challenging labels changed, predicting them again" in printed
    assert "test labels changed" not in printed and not (out / "f4_mixed_cs_features-s0").exists()
    summary = Summary.read(out / "summary.json")
    assert {m.name: m.paper_row for m in summary.models} == {
        "stam4": "f4_mixed_cs_features",
        "single": "f1_keyonly",
        "f4_add": "f4_add",
    }
    assert "SimpleAdd" in (out / "f4_add-s0" / "run" / "config.yaml").read_text()
    assert {(d.a, d.b) for d in summary.differences if d.kind == "models" and d.view == "test"} == {
        ("stam4", "single"),
        ("f4_add", "single"),
        ("f4_add", "stam4"),
    }
    again = json.loads((out / "single-s0" / "done.json").read_text())
    assert (
        again["scores"]["challenging"]["images"] == len(FACTORS) and again["scores"]["test"] == first["scores"]["test"]
    )
    rescored = json.loads(done.read_text())
    assert rescored["scoring"] == SCORING and rescored["scores"]["test"]["late"] == 1
    assert json.loads(preds.read_text().splitlines()[0])["run_time"] == 500.0  # not predicted again
    assert rescored["scores"]["test"]["f1"] == before["scores"]["test"]["f1"]


def _single_clean_is_the_single_frame_trained_without_the_key_frame_corruption(out: Path) -> None:
    assert main(["demo", "--quick", "--single-clean", *FEWER, "--out", str(out)]) == 0
    assert "key_corruption: 0.5" in (out / "single-s0" / "run" / "config.yaml").read_text()
    assert "key_corruption: 0.0" in (out / "single_clean-s0" / "run" / "config.yaml").read_text()
    assert json.loads((out / "single_clean-s0" / "done.json").read_text())["recipe_args"] is False
    summary = Summary.read(out / "summary.json")
    assert [m.name for m in summary.models] == ["stam4", "single", "single_clean"]
    for a, b in (("stam4", "single_clean"), ("single", "single_clean")):  # compared, with a clip interval
        diff = summary.difference(a, b, "challenging", "tusimple_f1")
        assert diff.ci95[0] <= diff.diff <= diff.ci95[1]
    compared = {(d.a, d.b) for d in summary.differences if d.kind == "models"}
    assert compared == {("stam4", "single"), ("stam4", "single_clean"), ("single", "single_clean")}


def test_score_split_iou_is_what_stamlane_eval_culane_says(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """The IoU F1 of a split equals ``stamlane-eval culane pred.json gt.json`` at the line width of its frame
    size, per image and in total; a lane moved by a line width is no longer a match, one moved by a pixel is."""
    from stamlane_eval.cli import main as eval_main

    root = tmp_path / "set"
    root.mkdir()
    (root / "dataset.json").write_text(json.dumps({"config": {"height": 360, "width": 640}}))
    rows = list(range(160, 360, 10))
    gts, preds = [], []
    for i in range(6):
        lanes = [[100 + 20 * i + k * (j - 10) for j in range(len(rows))] for k in (-3, 0, 3)]
        lanes[0][:4] = [-2] * 4  # a lane absent on the far rows
        gts.append({"raw_file": f"clips/test-{i:04d}/8.jpg", "lanes": lanes, "h_samples": rows})
        moved = {0: 0, 1: 1, 2: 14, 3: 40}.get(i, 0)  # px
        found = [[x + moved if x >= 0 else x for x in lane] for lane in lanes]
        if i == 4:
            found = found[1:]  # a lane missed
        elif i == 5:
            found.append([600] * len(rows))  # a lane too many
        preds.append({"raw_file": gts[-1]["raw_file"], "lanes": found, "h_samples": rows, "run_time": 10.0})
    (root / "test.json").write_text("".join(json.dumps(g) + "\n" for g in gts))
    pred_dir = tmp_path / "pred"
    pred_dir.mkdir()
    (pred_dir / "predictions.json").write_text("".join(json.dumps(p) + "\n" for p in preds))
    totals = score_split(pred_dir, root, "test", 1)
    per_image, clips = read_per_image(pred_dir)
    assert iou_width((360, 640)) == totals["iou_width"] == 12
    assert clips == [f"clips/test-{i:04d}" for i in range(6)] and "recall_visible" not in per_image  # no masks
    tp5 = [int(r[0]) for r in per_image["culane_f1@0.5"]]
    assert tp5[:2] == [3, 3] and tp5[3] == 0 and tp5[4] == 2  # 1 px: still a match; 40 px: none is
    capsys.readouterr()
    argv = ["culane", str(pred_dir / "predictions.json"), str(root / "test.json"), "--size", "640x360"]
    assert eval_main([*argv, "--width", "12", "--format", "json", "--per-image", str(tmp_path / "cu.jsonl")]) == 0
    official = json.loads(capsys.readouterr().out)
    for t in ("0.3", "0.5"):
        assert totals[f"culane_f1@{t}"] == pytest.approx(official[t]["f1"], abs=1e-12)
    cu = [json.loads(line) for line in (tmp_path / "cu.jsonl").read_text().splitlines()]
    assert [r["0.5"] for r in cu] == per_image["culane_f1@0.5"].astype(int).tolist()
    assert [r["0.3"] for r in cu] == per_image["culane_f1@0.3"].astype(int).tolist()


def test_rows_of_a_table_with_a_baseline_are_compared_with_it() -> None:
    """Table 8's rows against its baseline (2 unaligned frames summed) besides one frame and STAM; the baseline
    itself and rows of tables without one are not."""
    from stamlane.experiments.demo import MODELS

    rows = [*MODELS[:2], *(Row.paper_row(r) for r in ("f2_noalign_add", "f2_add", "f2_mixed_cs_gates", "f4_stpsa"))]
    found = pairs(rows)
    assert [p for p in found if p[1] == "f2_noalign_add"] == [
        ("f2_add", "f2_noalign_add"),
        ("f2_mixed_cs_gates", "f2_noalign_add"),
    ]
    assert ("f4_stpsa", "single") in found and ("f4_stpsa", "stam4") in found and len(found) == 1 + 4 * 2 + 2
    assert ("stam4", "f4_noalign_add") not in found  # Table 2's baseline was not trained


def test_report_command_prints_a_summary_and_refuses_a_bad_one(quick: Path, tmp_path: Path, capsys) -> None:
    assert main(["report", str(quick / "summary.json"), "--csv", str(tmp_path / "s.csv")]) == 0
    assert "History use" in capsys.readouterr().out
    lines = (tmp_path / "s.csv").read_text().splitlines()
    assert lines[0].startswith("kind,subject,b,view,metric") and any(
        line.startswith("history_key,stam4,stam4@key") for line in lines
    )
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"format": 99, "models": []}))
    assert main(["report", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert "newer than this stamlane reads" in err and len(err.splitlines()) == 1
    assert main(["report", str(quick / "summary.json"), "--models", "nope"]) == 2
    assert "no model nope" in capsys.readouterr().err


if sys.platform == "win32":  # pragma: no cover
    pytest.skip("the demo's folders use POSIX paths", allow_module_level=True)
