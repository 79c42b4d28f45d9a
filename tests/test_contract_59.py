"""Issue 59's cases of the contract (docs/safety.md): each a command run as a new user would, answered in one line
and exit status 2 (or done), nothing written where it must not be.

- an output folder that cannot be made (under a file; a place the OS refuses, even to root): every command's
  outputs go through one guarded ``mkdir`` (`stamlane.safety.guard.make_folder`);
- a checkpoint's recorded image size whose streaming buffers exceed the budget (`check_stream_buffers`);
- an owner file that is a folder; an interrupted ``synth`` run again with another layout or set.
"""

from __future__ import annotations

import errno
import json
import os
from collections.abc import Callable
from pathlib import Path
from types import SimpleNamespace

import cv2
import numpy as np
import pytest
import torch

from stamlane.cli import main
from stamlane.safety.budget import MAX_STREAM_BYTES, BudgetError, check_stream_buffers, stream_bytes
from stamlane.safety.guard import GuardError, check_outputs, make_folder
from tests.tiny_checkpoint import save_tiny_checkpoint

REPO = Path(__file__).resolve().parents[1]
SHIPPED = REPO / "src" / "stamlane" / "weights" / "stam4-synthetic.ckpt"
torch.set_num_threads(1)


def _refused(capsys: pytest.CaptureFixture[str], code: int, *says: str) -> str:
    err = capsys.readouterr().err.strip()
    ours = [line for line in err.splitlines() if line.startswith("stamlane")]
    assert code == 2 and len(ours) == 1 and "Traceback" not in err, (code, err)
    for word in says:
        assert word in ours[0], (word, ours[0])
    return ours[0]


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A tiny synthetic set, a folder of three frames, a small checkpoint and one recording 8192x8192 frames."""
    from stamlane.synth import SynthConfig, generate_dataset
    from stamlane.synth.layout import SplitCounts

    folder = tmp_path_factory.mktemp("inputs")
    root = folder / "set"
    generate_dataset(root, SplitCounts(train=1, test=1), seed=1, config=SynthConfig(width=128, height=72, num_frames=4))
    frames = folder / "frames"
    frames.mkdir()
    for i in range(3):
        cv2.imwrite(str(frames / f"{i}.jpg"), np.full((72, 128, 3), 40 * i, np.uint8))
    return {
        "set": root,
        "frames": frames,
        "ckpt": save_tiny_checkpoint(folder / "small.ckpt", 2, [32, 64]),
        "huge": save_tiny_checkpoint(folder / "huge.ckpt", 1, [8192, 8192]),
    }


# ---------------------------------------------------------------------------------------------- output folders
COMMANDS: dict[str, Callable[[dict[str, Path], Path], list[str]]] = {
    "predict": lambda i, out: ["predict", "--ckpt_path", str(SHIPPED), "--source", str(i["frames"]),
                               "--predictions.output_dir", str(out)],
    "stream": lambda i, out: ["stream", str(i["frames"]), "--ckpt", str(i["ckpt"]), "--out", str(out), "--no-video"],
    "export": lambda i, out: ["export", "--ckpt_path", str(i["ckpt"]), "--output", str(out / "m.onnx")],
    "export-streaming": lambda i, out: ["export", "--ckpt_path", str(i["ckpt"]), "--output",
                                        str(out.parent / "m.onnx"), "--streaming", str(out)],
    "synth": lambda i, out: ["synth", "--out", str(out), "--clips", "3", "--size", "128x72", "--frames", "4",
                             "--quiet"],
    "show": lambda i, out: ["show", "--root", str(i["set"]), "--labels", "train.json", "--out", str(out / "g.png"),
                            "--num-frames", "2", "--n", "1"],
    "align-visualize": lambda i, out: ["align", str(i["set"]), "--cache", str(out.parent / "cache"),
                                       "--num-frames", "2", "--visualize", str(out), "--quiet"],
    "demo": lambda i, out: ["demo", "--quick", "--data", str(i["set"]), "--out", str(out)],
}  # fmt: skip
"""Every command that writes a folder (or a file into one), with its output at ``out``."""


@pytest.fixture
def read_only(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A folder in which no folder can be made, as a read-only mount refuses root too (``os.access`` says yes)."""
    place = tmp_path / "read-only"
    place.mkdir()
    real_mkdir = os.mkdir

    def mkdir(path: str | os.PathLike[str], *args: object, **kwargs: object) -> None:
        if Path(path).resolve().is_relative_to(place.resolve()):
            raise PermissionError(errno.EROFS, os.strerror(errno.EROFS), os.fspath(path))
        real_mkdir(path, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(os, "mkdir", mkdir)
    return place


@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize("where", ["under-a-file", "read-only"])
def test_an_output_folder_that_cannot_be_made_is_one_line(
    inputs: dict[str, Path],
    tmp_path: Path,
    request: pytest.FixtureRequest,
    capsys: pytest.CaptureFixture[str],
    command: str,
    where: str,
) -> None:
    if where == "under-a-file":
        (tmp_path / "a-file").write_text("x")
        out = tmp_path / "a-file" / "out"
    else:
        out = request.getfixturevalue("read_only") / "out"
    before = {p.name: sorted(q.name for q in p.rglob("*")) for p in inputs.values() if p.is_dir()}
    code = main(COMMANDS[command](inputs, out))
    line = _refused(capsys, code)
    assert "out" in line and ("a-file" in line or "read-only" in line), line
    assert not os.path.lexists(out)
    assert {p.name: sorted(q.name for q in p.rglob("*")) for p in inputs.values() if p.is_dir()} == before


def test_make_folder_says_why_in_one_line(tmp_path: Path, read_only: Path) -> None:
    (tmp_path / "f").write_text("x")
    with pytest.raises(GuardError, match=r"--out .*f/x cannot be created: Not a directory"):
        make_folder(tmp_path / "f" / "x", "--out")
    with pytest.raises(GuardError, match="cannot be created: Read-only file system"):
        make_folder(read_only / "a" / "b")
    assert make_folder(tmp_path / "new" / "deep").is_dir()


def test_a_read_only_file_system_is_refused_before_any_work(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``check_outputs`` asks the file system, not only the permission bits (root passes ``os.access``)."""
    real = os.statvfs

    def statvfs(path: str | os.PathLike[str]) -> object:
        found = real(path)
        flag = found.f_flag | os.ST_RDONLY if Path(path) == tmp_path else found.f_flag
        return SimpleNamespace(f_flag=flag)

    monkeypatch.setattr(os, "statvfs", statvfs)
    with pytest.raises(GuardError, match="read-only file system"):
        check_outputs([tmp_path / "x.json"], folders=[tmp_path / "out"])


# ---------------------------------------------------------------------------------------------- the stream budget
def test_a_huge_recorded_image_size_is_refused_before_a_buffer_is_made(
    inputs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """One frame of 8192x8192 passes the clip budget (64 Mi px) and needs ~18 GiB of buffers in the predictor."""
    import resource

    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    argv = ["stream", str(inputs["frames"]), "--ckpt", str(inputs["huge"]), "--out", str(tmp_path / "s")]
    _refused(capsys, main(argv), "8192x8192", "GiB", "budget")
    assert (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - peak) * 1024 < 2**30
    assert not (tmp_path / "s").exists()
    argv = [*argv[:-1], str(tmp_path / "t"), "--image-size", "4096", "8192"]  # a flag goes through it too
    _refused(capsys, main(argv), "4096x8192")


def test_the_stream_budget_fits_what_the_paper_runs() -> None:
    paper = ([64, 128, 256, 512, 512], [1, 2, 4, 8, 16], 4)
    assert stream_bytes(8, (1080, 1920), *paper) < MAX_STREAM_BYTES / 2  # full HD, full width, 8 frames
    assert check_stream_buffers(5, (368, 640), *paper) > 0
    small = ([8, 16, 32, 64, 64], [1, 2, 4, 8, 16], 4)
    with pytest.raises(BudgetError, match="8192x8192"):
        check_stream_buffers(1, (8192, 8192), *small)
    # the count is of the same order as what the predictor holds: ~262 B/px measured at 2048x2048 (CPU)
    assert 200 < stream_bytes(2, (2048, 2048), *small) / 2048**2 < 400


def test_the_predictor_checks_its_buffers_in_its_constructor() -> None:
    from stamlane.models import STAM, LaneDecoder, LaneNet, VGGEncoder
    from stamlane.stream.predictor import StreamingPredictor

    net = LaneNet(VGGEncoder(width=0.125), STAM, LaneDecoder)
    with pytest.raises(BudgetError, match="the streaming predictor"):
        StreamingPredictor(net, 1, (8192, 8192))
    assert StreamingPredictor(net, 2, (32, 64)).image_size == (32, 64)


# ---------------------------------------------------------------------------------------------- owner files
def test_an_owner_file_that_is_a_folder_is_one_line(
    inputs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    (out / ".stamlane-owner.json").mkdir(parents=True)
    _refused(capsys, main(COMMANDS["predict"](inputs, out)), ".stamlane-owner.json", "--predictions.output_dir")
    assert [p.name for p in out.iterdir()] == [".stamlane-owner.json"]
    _refused(capsys, main(COMMANDS["stream"](inputs, out)), ".stamlane-owner.json", "--out")


# ---------------------------------------------------------------------------------------------- synth
@pytest.mark.parametrize("change", [["--layout", "tusimple"], ["--clips", "4"], ["--size", "160x90"]])
def test_an_interrupted_synth_set_is_written_again_only_as_it_was_asked(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], change: list[str]
) -> None:
    out = tmp_path / "set"
    argv = ["synth", "--out", str(out), "--clips", "3", "--size", "128x72", "--frames", "4", "--quiet"]
    argv += ["--challenging-clips", "0", "--reveal-clips", "0", "--reveal-traffic-clips", "0"]
    assert main(argv) == 0
    (out / "dataset.json").unlink()  # what an interrupted run leaves: every file but the record, written last
    before = sorted(p.relative_to(out).as_posix() for p in out.rglob("*"))
    _refused(capsys, main([*argv, *change]), str(out), "--out", "another")
    assert sorted(p.relative_to(out).as_posix() for p in out.rglob("*")) == before
    assert main(argv) == 0  # the same run again completes the set
    assert "layout" not in json.loads((out / "dataset.json").read_text())  # the generator's own layout


# ---------------------------------------------------------------------------------------------- refused classes
REFUSED_CLASSES = {
    "callback-optimizer": ("trainer:\n  callbacks:\n    - class_path: torch.optim.AdamW\n", "trainer.callbacks",
                           "torch.optim.AdamW"),
    "callback-function": ("trainer:\n  callbacks:\n    - class_path: os.system\n", "trainer.callbacks", "os.system"),
    "logger-function": ("trainer:\n  logger:\n    class_path: os.system\n", "trainer.logger", "os.system"),
    "logger-callback": ("trainer:\n  logger:\n    class_path: lightning.pytorch.callbacks.ModelCheckpoint\n",
                        "trainer.logger", "lightning.pytorch.callbacks.ModelCheckpoint"),
    "optimizer-function": ("model:\n  optimizer: os.system\n", "model.optimizer", "os.system"),
    "optimizer-scheduler": ("model:\n  optimizer:\n    class_path: torch.optim.lr_scheduler.LambdaLR\n",
                            "model.optimizer", "torch.optim.lr_scheduler.LambdaLR"),
    "optimizer-class-path": ("model:\n  optimizer:\n    class_path: os.system\n", "model.optimizer", "os.system"),
}  # fmt: skip
"""A ``--config`` naming a class of the wrong kind where a callback, a logger or an optimizer goes."""


@pytest.mark.parametrize("case", sorted(REFUSED_CLASSES))
def test_a_refused_class_in_a_config_is_one_short_line(
    inputs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str], case: str
) -> None:
    text, key, name = REFUSED_CLASSES[case]
    (tmp_path / "c.yaml").write_text(text)
    argv = ["fit", "--config", str(REPO / "configs" / "demo.yaml"), "--config", str(tmp_path / "c.yaml")]
    line = _refused(capsys, main([*argv, f"--data.root={inputs['set']}", f"--trainer.default_root_dir={tmp_path}"]))
    assert key in line and name in line and len(line) < 200, line


@pytest.mark.parametrize("case", ["callback", "logger", "optimizer", "scheduler-as-optimizer"])
def test_a_class_a_stored_config_may_not_name_is_one_short_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], case: str
) -> None:
    import yaml

    from stamlane.training.lightning_cli import CONFIG_KEY

    content = torch.load(SHIPPED, map_location="cpu", weights_only=True)
    stored = yaml.safe_load(content[CONFIG_KEY])
    key, name = {
        "callback": ("trainer.callbacks[0].class_path", "lightning.pytorch.callbacks.LambdaCallback"),
        "logger": ("trainer.logger.class_path", "os.system"),
        "optimizer": ("model.optimizer", "os.system"),
        "scheduler-as-optimizer": ("model.optimizer.class_path", "torch.optim.lr_scheduler.LambdaLR"),
    }[case]
    section, option = key.split(".")[0], key.split(".")[1].split("[")[0]
    value: object = name if key.endswith(option) else {"class_path": name}
    stored[section][option] = [value] if "[0]" in key else value
    content[CONFIG_KEY] = yaml.safe_dump(stored)
    ckpt = tmp_path / "c.ckpt"
    torch.save(content, ckpt)
    line = _refused(capsys, main(["validate", "--ckpt_path", str(ckpt)]), key, name, "registry")
    assert len(line) - len(str(ckpt)) < 200, line


# ---------------------------------------------------------------------------------------------- show: name the file
SHOW_LABELS = {
    "nul-raw-file": ("tusimple", "nul.json", "holds a NUL byte"),
    "long-raw-file": ("tusimple", "long.json", "over the file system's limit of 255"),
    "long-raw-path": ("tusimple", "longpath.json", "over the file system's limit of 4096"),
    "gzip-list": ("culane", "list.txt.gz", "not UTF-8"),
    "nul-list": ("culane", "nul.txt", "holds a NUL byte"),
}


@pytest.mark.parametrize("case", sorted(SHOW_LABELS))
def test_show_names_the_label_or_list_file(
    inputs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str], case: str
) -> None:
    import gzip
    import shutil

    root = tmp_path / "set"
    shutil.copytree(inputs["set"], root)
    line = json.loads((root / "train.json").read_text().splitlines()[0])
    for name, raw in (("nul", "clips/a\x00b/4.jpg"), ("long", "clips/" + "a" * 300 + "/4.jpg")):
        (root / f"{name}.json").write_text(json.dumps(line | {"raw_file": raw}) + "\n")
    (root / "longpath.json").write_text(json.dumps(line | {"raw_file": "/".join(["b" * 200] * 30)}) + "\n")
    (root / "list.txt.gz").write_bytes(gzip.compress(b"clips/0000/4.jpg\n"))
    (root / "nul.txt").write_bytes(b"clips/0000/4\x00.jpg\n")
    fmt, name, says = SHOW_LABELS[case]
    argv = ["show", "--root", str(root), "--labels", name, "--format", fmt, "--out", str(tmp_path / "g.png")]
    line = _refused(capsys, main([*argv, "--num-frames", "2"]), name, says)
    assert len(line) < 300 and not (tmp_path / "g.png").exists(), line


# ---------------------------------------------------------------------------------------------- demo: name the run
@pytest.mark.parametrize("case", ["dangling-checkpoint", "dots-in-run", "link-outside"])
def test_a_refused_run_record_names_the_run(tmp_path: Path, case: str) -> None:
    from stamlane.experiments.store import ExperimentError, RunStore

    top, name = tmp_path / "out", "stam4-s0"
    run = top / name / "run"
    ckpt = run / "checkpoints" / "last.ckpt"
    ckpt.parent.mkdir(parents=True)
    record = {"data": "d", "run": str(run), "last_ckpt": str(ckpt), "frames": 4, "scores": {}, "labels": {}}
    if case == "dangling-checkpoint":
        ckpt.symlink_to(tmp_path / "gone.ckpt")
    elif case == "dots-in-run":
        record["run"] = str(top / name / ".." / ".." / "elsewhere")
    done = top / name / "done.json"
    if case == "link-outside":
        (tmp_path / "theirs.json").write_text(json.dumps(record))
        done.symlink_to(tmp_path / "theirs.json")
    else:
        done.write_text(json.dumps(record))
    with pytest.raises(ExperimentError, match=f"^run {name}: ") as caught:
        RunStore(top).finished(name, {"data": "d"})
    assert len(str(caught.value).splitlines()) == 1


# ---------------------------------------------------------------------------------------------- stored choices
def test_a_stored_config_does_not_choose_what_predict_reads(
    inputs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A checkpoint whose config names ``source: /elsewhere`` (and a ``predictions.output_dir`` there): ``predict
    --data.root ROOT`` predicts ROOT's split and writes where the command chooses, nothing read or written there."""
    import shutil

    import yaml

    from stamlane.training.lightning_cli import CONFIG_KEY

    elsewhere = tmp_path / "elsewhere"
    shutil.copytree(inputs["frames"], elsewhere)
    content = torch.load(SHIPPED, map_location="cpu", weights_only=True)
    stored = yaml.safe_load(content[CONFIG_KEY])
    stored["source"] = str(elsewhere)
    stored["predictions"]["output_dir"] = str(elsewhere / "out")
    content[CONFIG_KEY] = yaml.safe_dump(stored)
    ckpt = tmp_path / "c.ckpt"
    torch.save(content, ckpt)
    monkeypatch.chdir(tmp_path)
    before = sorted(p.name for p in elsewhere.iterdir())
    assert main(["predict", "--ckpt_path", str(ckpt), "--data.root", str(inputs["set"])]) == 0
    made = sorted(p.name for p in (tmp_path / "outputs" / "predict" / "c").iterdir())
    assert made == ["set-test"], made  # the set's test split, as the docs say, not the stored source
    assert sorted(p.name for p in elsewhere.iterdir()) == before


# ---------------------------------------------------------------------------------------------- sizes in checkpoints
def test_a_network_larger_than_its_weights_is_never_built(
    inputs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """An encoder ``width`` of 64 in a checkpoint's hyper_parameters asks ~300 GB of parameters: counted on the
    ``meta`` device against the stored weights, refused before one is allocated."""
    import resource

    content = torch.load(inputs["ckpt"], weights_only=True)
    content["hyper_parameters"]["encoder"] = {"class_path": "stamlane.models.VGGEncoder", "init_args": {"width": 64.0}}
    torch.save(content, tmp_path / "wide.ckpt")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    argv = ["stream", str(inputs["frames"]), "--ckpt", str(tmp_path / "wide.ckpt"), "--out", str(tmp_path / "s")]
    _refused(capsys, main(argv), "wide.ckpt", "its weights hold")
    assert (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - peak) * 1024 < 2**30


def test_export_counts_the_clip_it_traces(inputs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    argv = ["export", "--ckpt_path", str(inputs["huge"]), "--output", str(tmp_path / "m.onnx")]
    _refused(capsys, main(argv), "8192x8192", "budget")
    assert not (tmp_path / "m.onnx").exists()


def test_a_checkpoint_folder_inside_the_data_is_refused_before_fit(
    inputs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Lightning's own writer (a ``ModelCheckpoint`` with its ``dirpath``) goes through the output guard too."""
    config = tmp_path / "c.yaml"
    callback = "    - class_path: lightning.pytorch.callbacks.ModelCheckpoint\n"
    config.write_text(f"trainer:\n  callbacks:\n{callback}      init_args:\n        dirpath: {inputs['set'] / 'ck'}\n")
    argv = ["fit", "--config", str(REPO / "configs" / "demo.yaml"), "--config", str(config)]
    argv += [f"--data.root={inputs['set']}", f"--trainer.default_root_dir={tmp_path / 'run'}"]
    _refused(capsys, main(argv), "ck", "input")
    assert not (inputs["set"] / "ck").exists() and not (tmp_path / "run").exists()


# ---------------------------------------------------------------------------------------------- several processes
@pytest.mark.parametrize("bad", [0, 3], ids=["rank-0-share", "rank-1-share"])
def test_a_bad_frame_under_ddp_ends_every_process_with_its_line(tmp_path: Path, bad: int) -> None:
    """Two CPU processes (gloo): the process that meets a truncated frame says it and stops; the other, whose
    collective breaks, says the same line (`stamlane.safety.boundary.peer_failure`), not gloo's traceback."""
    import subprocess
    import sys

    from stamlane.synth import SynthConfig, generate_dataset
    from stamlane.synth.layout import SplitCounts

    root = tmp_path / "set"
    generate_dataset(
        root, SplitCounts(train=1, val=4, test=1), seed=1, config=SynthConfig(width=128, height=72, num_frames=2)
    )
    frame = root / "clips" / f"val-{bad:04d}" / "2.jpg"
    frame.write_bytes(frame.read_bytes()[:200])
    env = {**os.environ, "OMP_NUM_THREADS": "1", "OMP_WAIT_POLICY": "PASSIVE", "PYTHONWARNINGS": "ignore"}
    args = ["validate", "--ckpt_path=single-synthetic", f"--data.root={root}", "--data.loader.batch_size=1"]
    args += ["--data.loader.num_workers=0", f"--trainer.default_root_dir={tmp_path / 'run'}"]
    args += ["--trainer.enable_progress_bar=false", "--trainer.strategy=ddp", "--trainer.devices=2"]
    args += ["--trainer.accelerator=cpu"]
    proc = subprocess.run(
        [sys.executable, "-m", "stamlane.cli", *args], env=env, capture_output=True, text=True, timeout=300
    )
    said = [line for line in proc.stderr.splitlines() if line.startswith("stamlane validate")]
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr[-3000:]
    assert len(said) == 2 and said[0] == said[1] and f"val-{bad:04d}/2.jpg" in said[0], said
