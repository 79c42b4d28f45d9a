"""``stamlane fit|validate|test|predict`` (StamLaneCLI): configs, fit -> predict -> stamlane-eval, resume (DDP: tests/training/test_distributed.py)."""

from __future__ import annotations

import csv
import json
import sys
from collections.abc import Callable
from pathlib import Path

import cv2
import lightning.pytorch as pl
import pytest
import torch
from stamlane_eval.cli import main as eval_main

from stamlane.cli import main
from stamlane.safety.owner import OWNER_NAME
from stamlane.training.lightning_cli import StamLaneCLI
from tests.training.tiny_runs import shrunk_demo_args

REPO = Path(__file__).resolve().parents[1]
CONFIGS = sorted((REPO / "configs").glob("*.yaml"))
torch.set_num_threads(1)


pytestmark = pytest.mark.usefixtures("plain_argv")  # LightningCLI warns when sys.argv holds pytest's own args


@pytest.fixture(scope="module")
def tiny_set(tiny_synthetic: Callable[..., Path]) -> Path:
    """4 train, 2 val, 2 test clips of 4 frames at 256x144 (a few seconds to write)."""
    return tiny_synthetic(256, 144, 4, train=4, val=2, test=2, challenging=0)


def _args(root: Path, out: Path, *extra: str) -> list[str]:
    """The demo config shrunk: 2 frames at 64x128, width 1/8, 2 clips a batch (2 steps an epoch)."""
    return shrunk_demo_args(root, out, *extra, size="[64, 128]", width=0.125)


@pytest.mark.parametrize("config", CONFIGS, ids=[c.stem for c in CONFIGS])
def test_config_loads(config: Path, capsys: pytest.CaptureFixture) -> None:
    with pytest.raises(SystemExit) as exc:
        StamLaneCLI(args=["fit", "--config", str(config), "--print_config"], run=True)
    assert exc.value.code in (0, None)
    out = capsys.readouterr().out
    assert "class_path: stamlane.models.VGGEncoder" in out and "num_frames:" in out


def test_fit_predict_then_stamlane_eval(
    tiny_set: Path, tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    assert main(["fit", *_args(tiny_set, tmp_path, "--trainer.max_steps=4", "--trainer.val_check_interval=2")]) == 0
    version = tmp_path / "stam4" / "version_0"
    said = capsys.readouterr().out  # where the model went and how good it is
    assert "stamlane fit: done after 4 steps" in said
    assert "best val/tusimple_f1 " in said and f"{version / 'checkpoints'}/best-step=" in said
    assert f"last (final weights): {version / 'checkpoints' / 'last.ckpt'}" in said
    assert f"logs and config: {version}" in said
    rows = list(csv.DictReader((version / "metrics.csv").open()))
    logged = {k for row in rows for k, v in row.items() if v}
    assert {"val/tusimple_f1", "val/tusimple_accuracy", "val/culane_f1@0.5", "val/loss"} <= logged
    ckpt = version / "checkpoints" / "last.ckpt"
    assert ckpt.is_file()
    assert torch.load(ckpt, weights_only=True)["global_step"] == 4  # loads without pickled objects

    config = str(version / "config.yaml")
    assert main(["predict", "--config", config, f"--ckpt_path={ckpt}", "--trainer.logger=false"]) == 0
    pred = tmp_path / "predictions" / "predictions.json"
    records = [json.loads(line) for line in pred.read_text().splitlines()]
    assert [r["raw_file"] for r in records] == ["clips/test-0000/4.jpg", "clips/test-0001/4.jpg"]
    assert len(list((tmp_path / "predictions" / "overlays").rglob("*.jpg"))) == 2
    capsys.readouterr()
    assert eval_main(["tusimple", str(pred), str(tiny_set / "test.json"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["images"] == 2

    # a folder of frames instead of the split: CULane text, one file per frame, in a folder of its own by default
    monkeypatch.chdir(tmp_path)
    frames = tiny_set / "clips" / "val-0000"
    args = [f"--ckpt_path={ckpt}", "--trainer.logger=false"]  # the run's config from the checkpoint
    capsys.readouterr()
    assert main(["predict", *args, f"--source={frames}"]) == 0
    out = Path("outputs/predict/stam4-version_0/val-0000")  # the run, the source
    assert sorted(p.name for p in (out / "lines").iterdir()) == [f"{i}.lines.txt" for i in range(1, 5)]
    said = capsys.readouterr()
    assert f"wrote 4 culane, 4 overlays under {out}\n" in said.out and "warning" not in said.err  # one sequence

    # a video file: decoded into a temporary folder, then the same, and every frame in overlay.mp4
    video = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 5, (256, 144))
    for i in range(1, 5):
        writer.write(cv2.imread(str(frames / f"{i}.jpg")))
    writer.release()
    assert main(["predict", *args, f"--source={video}"]) == 0
    out = Path("outputs/predict/stam4-version_0/clip")
    assert len(list((out / "lines").iterdir())) == 4 and len(list((out / "overlays").iterdir())) == 4
    assert capsys.readouterr().out.endswith(f"overlay.mp4 (4 frames) under {out}\n")
    overlay = cv2.VideoCapture(str(out / "overlay.mp4"))
    shown = []
    while (frame := overlay.read())[0]:
        shown.append(frame[1])
    assert len(shown) == 4 and shown[0].shape == (144, 256, 3) and overlay.get(cv2.CAP_PROP_FPS) == 5
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith("clip")) == ["clip.avi"]  # nothing beside
    assert not [p for p in out.iterdir() if p.name.startswith(".") and p.name != OWNER_NAME]  # no temporary left

    # images that are not one sequence, used as history: one line says so
    unrelated = tmp_path / "unrelated"
    unrelated.mkdir()
    for i in (1, 2, 3):  # three frames, each upside down from the one before: the content jumps at every pair
        image = cv2.imread(str(frames / f"{i}.jpg"))
        cv2.imwrite(str(unrelated / f"{i}.jpg"), image[::-1] if i == 2 else image)
    assert main(["predict", *args, f"--source={unrelated}"]) == 0
    warned = [line for line in capsys.readouterr().err.splitlines() if "warning" in line]
    assert len(warned) == 1 and warned[0].startswith(
        f"stamlane predict: warning: {unrelated} is not one sequence: the content jumps between 2 of 2 frame pairs"
    )
    assert warned[0].endswith(
        "every frame is read with the frame before it as history (--data.history_source key: each frame alone)"
    )
    assert main(["predict", *args, f"--source={unrelated}", "--data.history_source=key"]) == 0
    assert "warning" not in capsys.readouterr().err
    mixed = tmp_path / "mixed"  # two sizes: refused before a frame is predicted
    mixed.mkdir()
    for i in (1, 2):
        image = cv2.imread(str(frames / f"{i}.jpg"))
        cv2.imwrite(str(mixed / f"{i}.jpg"), image if i < 2 else cv2.resize(image, (128, 72)))
    assert main(["predict", *args, f"--source={mixed}"]) == 2
    assert capsys.readouterr().err == (
        f"stamlane predict: {mixed} is not one sequence: 2 image sizes (1 of 256x144, 1 of 128x72); a clip's frames "
        "share one size (--data.history_source key: each frame alone)\n"
    )
    assert main(["predict", *args, f"--source={mixed}", "--data.history_source=key"]) == 0
    # the new options, given nonsense: one line, status 2
    for bad, message in (
        ("--data.history_source=other_clip", "history_source must be one of ('real', 'key') for a folder or video"),
        ("--predictions.video=maybe", "predictions.video"),
    ):
        assert main(["predict", *args, f"--source={unrelated}", bad]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and message in err, err

    # predict from the checkpoint alone: the run's config travels inside it; the split's own folder by default
    assert main(["predict", f"--ckpt_path={ckpt}", "--trainer.logger=false"]) == 0
    alone = Path(f"outputs/predict/stam4-version_0/{tiny_set.name}-test")
    assert (alone / "predictions.json").is_file() and len(list((alone / "overlays").rglob("*.jpg"))) == 2
    assert not (tmp_path / "outputs" / "demo").exists()  # the config's old prediction folder is not used

    def lanes(path: Path) -> list:
        return [(r["raw_file"], r["lanes"]) for r in map(json.loads, path.read_text().splitlines())]

    assert lanes(alone / "predictions.json") == lanes(pred)  # the same model, the same lanes
    lone = tmp_path / "lone.ckpt"  # a checkpoint without a config, far from its run folder: a stored model still
    content = torch.load(ckpt, weights_only=True)  # (its network and data options are its hyper-parameters)
    del content["stamlane_config"]
    torch.save(content, lone)
    assert main(["predict", f"--ckpt_path={lone}", f"--data.root={tiny_set}", "--predictions.output_dir=lone"]) == 0
    assert lanes(Path("lone") / "predictions.json") == lanes(pred)

    # the checkpoint alone rebuilds the network (only stamlane's classes and torch.optim are built from it)
    from stamlane.training.module import StamLaneModule

    module = StamLaneModule.from_checkpoint(ckpt)
    assert module.num_frames == 2 and not module.training

    # --ckpt_path last finds the run's last checkpoint instead of silently starting at step 0
    capsys.readouterr()
    resume = _args(tiny_set, tmp_path, "--trainer.max_steps=6", "--trainer.val_check_interval=2", "--ckpt_path=last")
    assert main(["fit", *resume]) == 0
    resumed = tmp_path / "stam4" / "version_1" / "checkpoints" / "last.ckpt"
    assert torch.load(resumed, weights_only=True)["global_step"] == 6
    rows = list(csv.DictReader((tmp_path / "stam4" / "version_1" / "metrics.csv").open()))
    assert min(int(r["step"]) for r in rows) >= 4  # it went on from step 4


def test_bad_data_root_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    args = _args(tmp_path / "missing", tmp_path, "--ckpt_path=null")
    assert main(["validate", *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("stamlane validate: ") and "missing" in err[-1] and "Traceback" not in "".join(err)


class _Kill(pl.Callback):
    """Dies (as a killed process would: no clean-up, no checkpoint) at the start of a given step."""

    def __init__(self, at_step: int) -> None:
        self.at_step = at_step

    def on_train_batch_start(self, trainer: pl.Trainer, *args: object) -> None:
        if trainer.global_step == self.at_step:
            raise _Killed


class _Killed(Exception):
    pass


def _fit_in_process(args: list[str], callbacks: list[pl.Callback] | None = None) -> StamLaneCLI:
    extra = {"trainer_defaults": {"callbacks": callbacks}} if callbacks else {}
    return StamLaneCLI(args=["fit", *args], **extra)


def test_resume_equals_uninterrupted_run(tiny_set: Path, tmp_path: Path) -> None:
    """Killed in the 3rd epoch, resumed from the mid-epoch step-3 checkpoint: the same weights as never killed."""
    common = [
        "--trainer.max_steps=6",  # 3 epochs of 2 steps
        "--trainer.val_check_interval=2",  # validation must not shift the training draws
        "--trainer.limit_val_batches=1",
        "--trainer.callbacks=[]",
        "--trainer.callbacks+=lightning.pytorch.callbacks.ModelCheckpoint",
        "--trainer.callbacks.monitor=null",
        "--trainer.callbacks.every_n_train_steps=3",
        "--trainer.callbacks.save_last=true",
    ]

    def args(name: str) -> list[str]:
        return [a for a in _args(tiny_set, tmp_path / name) if not a.startswith("--trainer.callbacks")] + common

    straight = _fit_in_process(args("a"))
    final = {k: v.clone() for k, v in straight.model.state_dict().items()}
    with pytest.raises(_Killed):
        _fit_in_process(args("b"), callbacks=[_Kill(at_step=5)])
    last = next((tmp_path / "b").rglob("last.ckpt"))
    assert torch.load(last, weights_only=True)["global_step"] == 3  # mid-epoch
    resumed = _fit_in_process([*args("b"), f"--ckpt_path={last}"])
    assert resumed.trainer.global_step == 6
    for key, value in resumed.model.state_dict().items():
        assert torch.equal(value, final[key]), key


def test_the_sky_cut_travels_from_the_data_to_the_model_and_the_streaming_predictor() -> None:
    from stamlane.stream import StreamingPredictor

    cli = StamLaneCLI(args=["--config", str(REPO / "configs" / "demo.yaml"), "--data.clip.crop_top=0.3"], run=False)
    assert cli.datamodule.clip.crop_top == 0.3 and cli.model.crop_top == 0.3
    assert cli.model.hparams["crop_top"] == 0.3  # in every checkpoint
    predictor = StreamingPredictor.from_module(cli.model)
    assert predictor.transform.crop_top == 0.3


def test_ckpt_path_last_without_a_run_is_one_line(tiny_set: Path, tmp_path: Path, capsys) -> None:
    assert main(["fit", *_args(tiny_set, tmp_path / "fresh", "--ckpt_path=last")]) == 2
    err = capsys.readouterr().err.strip()
    assert "--ckpt_path last: no last.ckpt under" in err and len(err.splitlines()) == 1


@pytest.mark.parametrize("content", [b"", b"not a checkpoint\n", b"PK\x03\x04truncated"])
def test_a_bad_checkpoint_is_one_line(content: bytes, tiny_set: Path, tmp_path: Path, capsys) -> None:
    bad = tmp_path / "bad.ckpt"
    bad.write_bytes(content)
    assert main(["validate", *_args(tiny_set, tmp_path, f"--ckpt_path={bad}")]) == 2
    err = capsys.readouterr().err.strip()
    assert f"checkpoint {bad}" in err and len(err.splitlines()) == 1 and "Traceback" not in err


def test_default_root_dir_moves_the_logs_and_tensorboard_logs_on_request(
    tiny_set: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """``--trainer.default_root_dir`` alone moves the config's CSV logger there too; a TensorBoard logger (the
    ``tensorboard`` extra) writes its event file where its save_dir says."""
    args = [a for a in _args(tiny_set, tmp_path / "unused", "--trainer.max_steps=2") if "logger" not in a]
    args = [a for a in args if not a.startswith("--trainer.default_root_dir")]
    root = tmp_path / "root"
    assert main(["fit", *args, f"--trainer.default_root_dir={root}"]) == 0
    assert (root / "stam4" / "version_0" / "config.yaml").is_file()
    assert (root / "stam4" / "version_0" / "checkpoints" / "last.ckpt").is_file()
    assert f"logs and config: {root / 'stam4' / 'version_0'}" in capsys.readouterr().out
    pytest.importorskip("tensorboardX", reason="the tensorboard extra is not installed")
    board = tmp_path / "tb"
    tensorboard = ["--trainer.logger=lightning.pytorch.loggers.TensorBoardLogger", f"--trainer.logger.save_dir={board}"]
    assert main(["fit", *args, *tensorboard]) == 0
    events = list(board.rglob("events.out.tfevents.*"))
    assert events and events[0].stat().st_size > 100
    assert (events[0].parent / "checkpoints" / "last.ckpt").is_file()


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ("--trainer.max_steps=-5", "`max_steps` must be a non-negative integer or -1"),
        ("--data.clip.image_size=[-16, 64]", "image_size must be (H, W) with sides >= 8, got (-16, 64)"),
        ("--data.clip.image_size=[40, 64]", "image_size must be positive multiples of the encoder stride 16"),
        ("--data.clip.num_frames=0", "num_frames must be >= 1, got 0"),
    ],
)
def test_bad_values_are_one_line(tiny_set: Path, tmp_path: Path, capsys, extra: str, message: str) -> None:
    assert main(["fit", *_args(tiny_set, tmp_path, extra)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len([line for line in err if line.startswith("stamlane fit:")]) == 1 and message in err[-1]
    assert not any("Traceback" in line for line in err)


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ("--trainer.max_stepz=3", "unrecognized arguments: --trainer.max_stepz=3"),
        ("--data.clip.num_frames=abc", 'Parser key "data.clip.num_frames": Expected'),
        ("--config=/nonexistent/x.yaml", "config /nonexistent/x.yaml does not exist"),
    ],
)
def test_bad_options_are_one_line_not_the_usage(
    tiny_set: Path, tmp_path: Path, capsys, extra: str, message: str
) -> None:
    """jsonargparse would print its whole usage (about a hundred lines) before the error."""
    assert main(["fit", *_args(tiny_set, tmp_path, extra)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("stamlane fit: ") and message in err[0], err[:3]
    assert err[0].endswith("(see stamlane fit --help)")


def test_a_data_error_in_a_dataloader_worker_is_one_line(tiny_set: Path, tmp_path: Path, capsys) -> None:
    import shutil

    root = tmp_path / "set"
    shutil.copytree(tiny_set, root)
    key = json.loads((root / "train.json").read_text().splitlines()[0])["raw_file"]
    frame = root / key
    frame.write_bytes(frame.read_bytes()[: len(frame.read_bytes()) // 2])  # a truncated JPEG
    args = _args(root, tmp_path / "out", "--trainer.max_steps=4", "--data.loader.num_workers=1")
    assert main(["fit", *args]) == 2
    err = [line for line in capsys.readouterr().err.strip().splitlines() if line.startswith("stamlane")]
    assert len(err) == 1 and "cannot read image" in err[0] and key in err[0]
    assert "Original Traceback" not in err[0] and "DataLoader worker" not in err[0]


QUIETED = ("LightningCLI's args parameter", "The dirpath has changed", "dataloader is not resumable")
"""The Lightning warnings the quiet front end drops where stamlane expects them (`stamlane.training.quiet.WARNINGS`)."""


def test_a_run_is_quiet_keeps_its_best_and_works_from_any_folder(
    tiny_set: Path, tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch, recwarn
) -> None:
    """A run started with a relative data root: a line per validation, a resume that says the true best, then
    validate / test / predict from another folder that find the data and add no ``version_N`` to the run."""
    start, elsewhere = tmp_path / "start", tmp_path / "elsewhere"
    (start / "data").mkdir(parents=True)
    elsewhere.mkdir()
    (start / "data" / "tiny").symlink_to(tiny_set)
    monkeypatch.chdir(start)
    # 2 steps an epoch: last.ckpt at step 3 is mid-epoch
    assert (
        main(
            ["fit", *_args(Path("data/tiny"), Path("runs"), "--trainer.max_steps=3", "--trainer.val_check_interval=2")]
        )
        == 0
    )
    said = capsys.readouterr().out
    assert "stamlane fit: step 2  val/tusimple_f1 " in said and "best " in said.splitlines()[0]
    best = next(line for line in said.splitlines() if line.startswith("  best val/tusimple_f1 "))
    score = best.split()[2]
    run = start / "runs" / "stam4"
    ckpt = run / "version_0" / "checkpoints" / "last.ckpt"
    assert torch.load(ckpt, weights_only=True)["stamlane_start_dir"] == str(start)

    # resumed without validating: the closing line says the best of the run it went on from, not nan
    resume = _args(Path("data/tiny"), Path("runs"), "--trainer.max_steps=4", "--trainer.val_check_interval=2")
    resume.append("--trainer.limit_val_batches=0")
    assert main(["fit", *resume, "--ckpt_path=last"]) == 0
    said = capsys.readouterr().out
    assert f"  best val/tusimple_f1 {score} at step 2: " in said and "nan" not in said, said
    assert str(Path("runs/stam4/version_0/checkpoints/best-step=2.ckpt")) in said

    monkeypatch.chdir(elsewhere)  # the run recorded data/tiny relative to start/
    for command in ("validate", "test"):
        monkeypatch.setattr(sys, "argv", ["stamlane", command, "--ckpt_path", str(ckpt)])
        assert main() == 0, capsys.readouterr().err
        assert f"stamlane {command}: metrics logged under {Path('runs') / f'stam4-{command}' / 'version_0'}" in (
            capsys.readouterr().out
        )
    out = tmp_path / "pred"
    assert main(["predict", f"--ckpt_path={ckpt}", f"--predictions.output_dir={out}"]) == 0
    assert (out / "predictions.json").is_file()
    assert sorted(p.name for p in run.iterdir()) == ["version_0", "version_1"]  # nothing added to the run
    assert not (elsewhere / "runs" / "stam4").exists()  # predict logs nothing
    said = [str(w.message) for w in recwarn]
    assert not [m for m in said if any(q in m for q in QUIETED)], said

    # found nowhere: the message names the flag to give
    (start / "data" / "tiny").unlink()
    capsys.readouterr()
    assert main(["validate", f"--ckpt_path={ckpt}"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "data root data/tiny" in err and err.endswith("give --data.root DIR"), err


def _logged(folder: Path) -> list[dict[str, str]]:
    """The rows of a validation's or test's ``metrics.csv`` (strings: compared to the bit)."""
    with open(folder / "metrics.csv") as file:
        return list(csv.DictReader(file))


def test_a_stored_run_scores_as_its_config_does(tiny_set: Path, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """``validate|test --ckpt_path CKPT`` (the stored model, one read, `stamlane.training.stored_cli`) logs the same
    numbers, to the bit, as LightningCLI given the run's config and the checkpoint; its logs follow a
    ``--trainer.default_root_dir`` given; ``--source`` and ``--weights_only false`` are one line, exit status 2."""
    assert main(["fit", *_args(tiny_set, tmp_path, "--trainer.max_steps=2")]) == 0
    run = tmp_path / "stam4" / "version_0"
    ckpt = run / "checkpoints" / "last.ckpt"
    for command in ("validate", "test"):
        capsys.readouterr()
        assert main([command, "--ckpt_path", str(ckpt)]) == 0
        stored = tmp_path / f"stam4-{command}"
        assert f"stamlane {command}: metrics logged under {stored / 'version_0'}" in capsys.readouterr().out
        assert main([command, "--config", str(run / "config.yaml"), "--ckpt_path", str(ckpt)]) == 0
        rows = _logged(stored / "version_0")
        assert rows and any(f"{'val' if command == 'validate' else 'test'}/tusimple_f1" in row for row in rows)
        assert rows == _logged(stored / "version_1")
    root = tmp_path / "elsewhere"
    assert main(["validate", "--ckpt_path", str(ckpt), f"--trainer.default_root_dir={root}"]) == 0
    assert (root / "stam4-validate" / "version_0" / "metrics.csv").is_file()
    capsys.readouterr()
    for extra, said in (("--source=frames", "--source is for predict only"), ("--weights_only=false", "weights_only")):
        assert main(["test", "--ckpt_path", str(ckpt), extra]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and err.startswith("stamlane test: ") and said in err, err
