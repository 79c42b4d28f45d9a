"""Runs from Python (`stamlane.training.runs`): a run made by `fit` is the run ``stamlane fit`` makes of the same config
and options, bit for bit; an opened run predicts several splits and probes with one model, each prediction the bytes
a fresh ``stamlane predict`` pass writes; records of before load; options are data and give back the flags of before;
LightningCLI never reads ``sys.argv``."""

from __future__ import annotations

import json
import sys
import warnings
from collections.abc import Callable
from pathlib import Path

import pytest
import torch

from stamlane.data.probes import HISTORIES, PROBES, Probe
from stamlane.safety.checkpoints import read_checkpoint
from stamlane.training.runs import (
    RecordError,
    Run,
    RunError,
    RunRecord,
    RunSpec,
    fit,
    flags_of,
    open_run,
    overrides_of,
    run_cli,
)

torch.set_num_threads(1)
REPO = Path(__file__).resolve().parents[2]
TINY = {
    "data.clip.num_frames": 2,
    "data.clip.image_size": [32, 64],
    "data.loader.batch_size": 2,
    "data.loader.num_workers": 0,
    "model.encoder.width": 0.0625,
    "model.bf16": False,
    "model.channels_last": False,
    "trainer.enable_progress_bar": False,
    "trainer.enable_model_summary": False,
    "trainer.max_steps": 2,
    "trainer.val_check_interval": 2,
}
"""The demo config shrunk to seconds (2 frames at 32x64, aligned on the fly as the demo is)."""


@pytest.fixture(scope="module")
def tiny_root(tiny_synthetic: Callable[..., Path]) -> Path:
    return tiny_synthetic(128, 72, 4, train=2, val=2, test=2, challenging=0)


@pytest.fixture(scope="module")
def tiny_run(tiny_root: Path, tmp_path_factory: pytest.TempPathFactory) -> RunRecord:
    spec = RunSpec((REPO / "configs" / "demo.yaml",), {"data.root": tiny_root, **TINY})
    return fit(spec, seed=3, run_dir=tmp_path_factory.mktemp("runs") / "tiny-s3" / "run")


def test_fit_makes_the_run_stamlane_fit_makes(tiny_run: RunRecord, tiny_root: Path, tmp_path: Path) -> None:
    from stamlane.cli import main

    assert tiny_run.frames == 2 and tiny_run.seed == 3 and tiny_run.last_ckpt.is_file()
    assert (tiny_run.run / "config.yaml").is_file() and tiny_run.run.name == "run"
    args = ["fit", "--config", str(REPO / "configs" / "demo.yaml"), f"--data.root={tiny_root}", *flags_of(TINY)]
    args += ["--seed_everything=3", f"--trainer.default_root_dir={tmp_path}", f"--trainer.logger.save_dir={tmp_path}"]
    assert main(args) == 0
    (cli_ckpt,) = tmp_path.rglob("last.ckpt")
    ours, theirs = read_checkpoint(tiny_run.last_ckpt)["state_dict"], read_checkpoint(cli_ckpt)["state_dict"]
    assert ours.keys() == theirs.keys()
    assert all(torch.equal(ours[k], theirs[k]) for k in ours)


def _fresh_pass(run: Run, root: Path, split: str, probe: Probe, out: Path) -> None:
    """One prediction pass as the runner made it before runs were opened once: a LightningCLI of its own."""
    from stamlane.training.registry import safe_config_file

    with safe_config_file(run.text, run.source) as config:
        options = {
            "data.root": root,
            "data.predict_labels": [f"{split}.json"],
            "data.history_source": probe.history,
            **({"data.clip.align": "true"} if probe.exact else {}),
            "trainer.logger": False,
            "trainer.callbacks": [],
            "trainer.enable_progress_bar": False,
            "predictions.verbose": False,
            "predictions.output_dir": out,
            "predictions.max_overlays": 0,
        }
        run_cli(["predict", "--config", str(config), f"--ckpt_path={run.ckpt}", *flags_of(options)])


def _lanes(folder: Path) -> list[dict]:
    """The predictions of a folder without their timings (``run_time``: the only value that varies between passes)."""
    lines = (folder / "predictions.json").read_text().splitlines()
    return [{k: v for k, v in json.loads(line).items() if k != "run_time"} for line in lines]


def test_an_opened_run_predicts_every_split_and_probe_with_one_model(
    tiny_root: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The shipped 4-frame model (trained: lanes that differ between probes), six passes with one stored model (its
    checkpoint read once), against a LightningCLI ``predict --config`` per pass: the same lanes and the same per-image
    scores, byte for byte."""
    from stamlane.experiments.split_scores import score_split
    from stamlane.safety import checkpoints
    from stamlane.weights import shipped_path

    built: list[object] = []
    monkeypatch.setattr(checkpoints, "read_checkpoint", _counting(checkpoints.read_checkpoint, built))
    passes = [("test", "exact"), ("test", "real"), ("val", "key"), ("test", "other_clip"), ("val", "exact")]
    passes += [("val", "warped_key")]  # exact first (the run's own alignment back after it), exact again later
    with open_run(shipped_path("stam4-synthetic")) as run:
        assert run.frames == 4 and run.aligns
        for split, probe in passes:
            run.predict(split, probe, tmp_path / "once" / f"{split}@{probe}", root=tiny_root)
        assert len(built) == 1  # one model (one read of the checkpoint) for every pass
        for split, probe in passes:
            _fresh_pass(run, tiny_root, split, Probe.of(probe), tmp_path / "fresh" / f"{split}@{probe}")
    for split, probe in passes:
        once, fresh = tmp_path / "once" / f"{split}@{probe}", tmp_path / "fresh" / f"{split}@{probe}"
        assert _lanes(once) == _lanes(fresh), (split, probe)
        assert _same(*(score_split(folder, tiny_root, split, 4) for folder in (once, fresh))), (split, probe)
        assert (once / "per_image.jsonl").read_bytes() == (fresh / "per_image.jsonl").read_bytes()
    lanes = {probe: _lanes(tmp_path / "once" / f"test@{probe}") for probe in ("exact", "real", "other_clip")}
    assert lanes["real"] != lanes["other_clip"]  # the probes were predicted as asked, not one pass repeated


def _same(a: dict, b: dict) -> bool:
    """Totals alike but for ``late`` (images over TuSimple's time limit: this machine's timing, not the model)."""
    return {k: v for k, v in a.items() if k != "late"} == {k: v for k, v in b.items() if k != "late"}


def _counting(method: Callable, calls: list) -> Callable:
    def counted(*args: object, **kwargs: object) -> object:
        calls.append(args)
        return method(*args, **kwargs)

    return counted


def test_open_run_is_the_gate(tiny_run: RunRecord, tmp_path: Path) -> None:
    from stamlane.training.lightning_cli import CONFIG_KEY

    run = open_run(tiny_run.last_ckpt)  # a checkpoint carries its config
    assert run.source == tiny_run.last_ckpt and run.frames == 2
    with pytest.raises(RunError, match=r"holds no checkpoints/last\.ckpt"):
        open_run(tmp_path)
    content = torch.load(tiny_run.last_ckpt, weights_only=True)
    content[CONFIG_KEY] = content[CONFIG_KEY].replace("stamlane.training.module.StamLaneModule", "os.system")
    content[CONFIG_KEY] += "\ntrainer:\n  callbacks:\n  - class_path: os.system\n"
    torch.save(content, tmp_path / "tampered.ckpt")
    with pytest.raises(RunError, match=r"os\.system"):
        open_run(tmp_path / "tampered.ckpt")
    (tmp_path / "foreign.ckpt").write_bytes(b"not a checkpoint")
    with pytest.raises(RunError):
        open_run(tmp_path / "foreign.ckpt")


def test_a_record_of_before_loads_and_a_tampered_one_is_refused() -> None:
    old = {  # a done.json of stamlane 0.x (before records were typed): settings and values side by side
        "recipe": "cpu",
        "pretrain_steps": 1200,
        "steps": 300,
        "row_args": ["--data.augment.key_corruption=0.5", "--data.augment.key_corruption_kinds=[blank, glare]"],
        "pretrain_args": [],
        "data": "/data/synthetic-v7",
        "seed": 0,
        "train_minutes": 2.4,
        "run": "/out/stam4-s0/run",
        "last_ckpt": "/out/stam4-s0/run/checkpoints/last.ckpt",
        "frames": 4,
        "hardware": "cpu: AMD EPYC, 2 threads, torch 2.5.1",
        "recipe_args": True,
        "pretrain_minutes": 3.0,
        "last_ckpt_sha256": "0" * 64,
        "scores": {"test": {"tusimple_f1": 0.9}},
        "labels": {"test": "1" * 64},
        "scoring": "no-time-limit+culane+classes",
    }
    record = RunRecord.from_json(old)
    assert record.run == Path("/out/stam4-s0/run") and record.frames == 4 and record.pretrain_minutes == 3.0
    assert record.settings["row_args"] == old["row_args"] and record.setting("data") == "/data/synthetic-v7"
    assert record.frame_files == {} and record.setting("run") == "/out/stam4-s0/run"
    assert record.to_json() == old and RunRecord.from_json(json.loads(json.dumps(record.to_json()))) == record
    older = {k: v for k, v in old.items() if k not in ("hardware", "recipe_args", "scores", "labels", "scoring")}
    assert RunRecord.from_json(older).recipe_args is True  # records of before recipes took row arguments
    for key, value in (("frames", "4"), ("frames", 0), ("frames", True), ("seed", None), ("run", 3), ("scores", [])):
        with pytest.raises(RecordError, match=key):
            RunRecord.from_json(old | {key: value})


def test_options_are_data_and_give_back_the_flags_typed() -> None:
    assert flags_of({"a.b": True, "c": None, "d": [64, 128], "e": Path("/x"), "f": ["a,b", "c"]}) == [
        "--a.b=true",
        "--c=null",
        "--d=[64, 128]",
        "--e=/x",
        '--f=["a,b", "c"]',  # JSON: what jsonargparse reads as this YAML list
    ]
    typed = ["--config", "a.yaml", "--trainer.max_steps", "5", "--data.root=/d", "--trainer.callbacks+=X"]
    assert overrides_of(typed) == {
        "config": ["a.yaml"],
        "trainer.max_steps": "5",
        "data.root": "/d",
        "trainer.callbacks+": "X",
    }
    assert flags_of(overrides_of(typed)) == [
        "--config",
        "a.yaml",
        "--trainer.max_steps=5",
        "--data.root=/d",
        "--trainer.callbacks+=X",
    ]
    # given twice: the last value holds, read last, as on a command line (the runner's extra after a recipe's own)
    assert list(overrides_of(["--a=1", "--b=2", "--a=3"]).items()) == [("b", "2"), ("a", "3")]
    for bad in (["x"], ["--a"], ["--c+=1", "--c+=2"]):
        with pytest.raises(RunError):
            overrides_of(bad)
    spec = RunSpec((Path("a.yaml"), Path("b.yaml")), {"x": 1}, base={"y": 2})
    assert spec.args() == ["--config", "a.yaml", "--y=2", "--config", "b.yaml", "--x=1"]
    assert spec.with_overrides({"x": 3, "z": 4}).overrides == {"x": 3, "z": 4}


def test_every_probe_has_one_home() -> None:
    assert HISTORIES == ("real", "key", "warped_key", "reversed", "other_clip")
    assert set(PROBES) == {*HISTORIES, "exact"} and PROBES["exact"].history == "real" and PROBES["exact"].exact
    assert Probe.of("warped_key").predicted_as(aligns=False).name == "key"
    assert Probe.of("warped_key").predicted_as(aligns=True).name == "warped_key"
    with pytest.raises(ValueError, match="known: real, key"):
        Probe.of("future")


def test_lightning_cli_never_reads_sys_argv(
    monkeypatch: pytest.MonkeyPatch, tiny_run: RunRecord, tmp_path: Path
) -> None:
    """The process's own command line (pytest's here) is neither read nor warned about."""
    monkeypatch.setattr(sys, "argv", ["pytest", "--not-an-option-of-stamlane", "-x"])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with open_run(tiny_run.run) as run:
            run.predict("test", "key", tmp_path / "p")
    assert not [w for w in caught if "argv" in str(w.message) or "args parameter" in str(w.message)]
    assert (tmp_path / "p" / "predictions.json").is_file()
    assert sys.argv == ["pytest", "--not-an-option-of-stamlane", "-x"]


def test_the_example_of_the_docs_runs(tiny_root: Path, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """docs/training.md "From Python", as written but for the data root and the output folder."""
    page = (REPO / "docs" / "training.md").read_text()
    code = page.split("## From Python", 1)[1].split("```python\n", 1)[1].split("```", 1)[0]
    code = code.replace('"data/synthetic-v7"', repr(str(tiny_root))).replace("outputs/python", str(tmp_path))
    exec(compile(code.replace('Path("configs/', f'Path("{REPO}/configs/'), "training.md", "exec"), {})
    frames = capsys.readouterr().out.split()[0]
    assert frames == "4" and (tmp_path / "stam4-s0" / "run" / "checkpoints" / "last.ckpt").is_file()
    for probe in ("real", "key", "other_clip"):
        assert (tmp_path / "predictions" / f"test@{probe}" / "predictions.json").is_file()
