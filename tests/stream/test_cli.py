"""``stamlane stream``: a checkpoint and a folder of frames in, lanes json-lines and an overlay video out."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch

from stamlane.align.egomotion import RoadCamera
from stamlane.align.synthetic import render_road, road_texture
from stamlane.safety.owner import OWNER_NAME
from stamlane.stream.cli import iter_frames, main

torch.set_num_threads(1)

NUM_FRAMES = 5
HPARAMS = {
    "encoder": {"class_path": "stamlane.models.VGGEncoder", "init_args": {"width": 0.125}},
    "fusion": {"class_path": "stamlane.models.STAM", "init_args": {"mode": "mixed", "reduction": 4}},
    "decoder": {"class_path": "stamlane.models.LaneDecoder", "init_args": {"embed_dim": 4}},
    "num_frames": 2,
    "image_size": [64, 128],
    "_instantiator": "lightning.pytorch.cli.instantiate_module",
}


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A checkpoint as `stamlane fit` writes it (hyper-parameters from the config, weights, data options)."""
    import lightning
    from lightning.pytorch.cli import instantiate_module

    from stamlane.training.module import StamLaneModule

    torch.manual_seed(0)
    module = instantiate_module(StamLaneModule, {k: v for k, v in HPARAMS.items() if k != "_instantiator"})
    path = tmp_path_factory.mktemp("ckpt") / "last.ckpt"
    torch.save(
        {
            "state_dict": module.state_dict(),
            "hyper_parameters": dict(HPARAMS),
            "datamodule_hyper_parameters": {"num_frames": 2, "image_size": [64, 128], "horizon_row": 100},
            "pytorch-lightning_version": lightning.__version__,
        },
        path,
    )
    return path


@pytest.fixture(scope="module")
def frames_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    camera = RoadCamera(width=320, height=180, focal=250.0, horizon_row=70.0, camera_height=1.5)
    texture = road_texture(seed=1)
    folder = tmp_path_factory.mktemp("frames")
    for i in range(NUM_FRAMES):
        cv2.imwrite(str(folder / f"{i:04d}.jpg"), render_road(texture, camera, forward=0.7 * i))
    return folder


def test_stream_writes_lanes_and_overlay(checkpoint: Path, frames_dir: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "out"
    assert main([str(frames_dir), "--ckpt", str(checkpoint), "--out", str(out)]) == 0
    records = [json.loads(line) for line in (out / "lanes.jsonl").read_text().splitlines()]
    assert [r["frame"] for r in records] == list(range(NUM_FRAMES))
    for record in records:
        assert isinstance(record["lanes"], list) and record["run_time"] > 0
        assert len(record["aligned"]) == 1  # T = 2 from the checkpoint: one history slot
        for lane in record["lanes"]:
            assert all(len(point) == 2 for point in lane)
    capture = cv2.VideoCapture(str(out / "overlay.mp4"))
    assert capture.isOpened()
    assert int(capture.get(cv2.CAP_PROP_FRAME_COUNT)) == NUM_FRAMES
    assert (int(capture.get(cv2.CAP_PROP_FRAME_WIDTH)), int(capture.get(cv2.CAP_PROP_FRAME_HEIGHT))) == (320, 180)
    capture.release()
    assert f"{NUM_FRAMES} frames" in capsys.readouterr().out


def test_options_override_the_checkpoint(checkpoint: Path, frames_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    argv = [str(frames_dir), "--ckpt", str(checkpoint), "--out", str(out), "--num-frames", "3", "--no-align"]
    assert main([*argv, "--max-frames", "2", "--no-video"]) == 0
    records = [json.loads(line) for line in (out / "lanes.jsonl").read_text().splitlines()]
    assert len(records) == 2 and all(r["aligned"] == [] for r in records)
    assert not (out / "overlay.mp4").exists()


def test_bf16_is_the_models_unless_given(checkpoint: Path, frames_dir: Path) -> None:
    from stamlane.stream.cli import build_parser, load_predictor
    from stamlane.training.module import StamLaneModule

    argv = [str(frames_dir), "--ckpt", str(checkpoint)]
    assert load_predictor(build_parser().parse_args(argv)).bf16 is StamLaneModule.from_checkpoint(checkpoint).bf16
    for flag, bf16 in (("true", True), ("false", False)):
        assert load_predictor(build_parser().parse_args([*argv, "--bf16", flag])).bf16 is bf16


def test_the_alignment_preset_is_the_checkpoints_unless_given(checkpoint: Path, frames_dir: Path) -> None:
    from stamlane.align.homography import ALIGN_PRESETS
    from stamlane.stream.cli import build_parser, load_predictor

    argv = [str(frames_dir), "--ckpt", str(checkpoint)]
    assert load_predictor(build_parser().parse_args(argv)).align_config == ALIGN_PRESETS["standard"]
    fast = load_predictor(build_parser().parse_args([*argv, "--align-preset", "fast"]))
    assert fast.align_config == ALIGN_PRESETS["fast"]


@pytest.mark.parametrize(
    ("argv", "match"),
    [
        (["missing.mp4", "--ckpt", "x.ckpt"], "does not exist"),
        (["{frames}", "--ckpt", "x.ckpt", "--align-preset", "quick"], "--align-preset: invalid choice: 'quick'"),
        (["{frames}"], "--ckpt CKPT or --config CFG"),
        (["{frames}", "--ckpt", "nowhere.ckpt"], "checkpoint nowhere.ckpt does not exist"),
        (["{empty}", "--ckpt", "x.ckpt"], "holds no image"),
        (["{frames}", "--ckpt", "x.ckpt", "--max-frames", "0"], "--max-frames must be >= 1"),
        (
            ["{frames}", "--ckpt", "x.ckpt", "--fps", "-5"],
            "--fps must be a finite rate in (0, 1000] frames/s, got -5.0",
        ),
        (["{frames}", "--ckpt", "x.ckpt", "--out", "{frames}"], "would overwrite or write into the input"),
        (["{frames}", "--ckpt", "x.ckpt", "--out", "{frames}/out"], "would overwrite or write into the input"),
        # the evaluator outputs' flags
        (["{frames}", "--ckpt", "x.ckpt", "--tusimple", "--sequence", "../up"], "--sequence must be a relative path"),
        (["{frames}", "--ckpt", "x.ckpt", "--culane", "--sequence", "/abs"], "--sequence must be a relative path"),
        (["{frames}", "--ckpt", "x.ckpt", "--culane", "--sequence", "a//b"], "--sequence must be a relative path"),
        (["{frames}", "--ckpt", "x.ckpt", "--culane", "--sequence", "a\nb"], "--sequence must be a relative path"),
        (["{frames}", "--ckpt", "x.ckpt", "--culane", "--sequence", "a\\b"], "--sequence must be a relative path"),
        (["{frames}", "--ckpt", "x.ckpt", "--sequence", "s"], "give one of them"),
        (["{frames}", "--ckpt", "x.ckpt", "--tusimple", "--first-frame", "x.jpg"], "--first-frame must be a frame"),
        (["{frames}", "--ckpt", "x.ckpt", "--tusimple", "--first-frame", "../1.jpg"], "--first-frame must be a frame"),
        (["{frames}", "--ckpt", "x.ckpt", "--tusimple", "--first-frame", "1.jpg"], "names a video's frames"),
        (["{frames}", "--ckpt", "x.ckpt", "--h-samples", "10", "5", "1"], "--h-samples START STOP STEP must"),
        (["{frames}", "--ckpt", "x.ckpt", "--h-samples", "0", "100000", "1"], "--h-samples START STOP STEP must"),
        (["{frames}", "--ckpt", "x.ckpt", "--h-samples", "0", "10", "0"], "--h-samples START STOP STEP must"),
        (["{frames}", "--ckpt", "x.ckpt", "--h-samples", "-1", "10", "1"], "--h-samples START STOP STEP must"),
        (["{frames}", "--ckpt", "x.ckpt", "--h-samples", "a", "b", "c"], "--h-samples: invalid int value"),
        (["{frames}", "--ckpt", "x.ckpt", "--bf16", "maybe"], "--bf16: invalid choice"),
        (["{frames}", "--ckpt", "x.ckpt", "--tusimple", "--out", "{file}"], "is a file, not a folder"),
        (["{frames}", "--ckpt", "x.ckpt", "--tusimple", "--out", "{taken}"], "predictions.json is a folder"),
        (["{frames}", "--ckpt", "x.ckpt", "--culane", "--out", "{taken}"], "lines is a file, not a folder"),
        (["{odd}", "--ckpt", "x.ckpt", "--tusimple"], "--sequence (default: the folder's name) must be a"),
    ],
)
def test_bad_input_is_one_line_and_status_2(
    argv: list[str], match: str, frames_dir: Path, tmp_path: Path, capsys
) -> None:
    (tmp_path / "empty").mkdir()
    (tmp_path / "file").write_text("x")
    (tmp_path / "taken" / "predictions.json").mkdir(parents=True)  # outputs in the way: a folder, a file
    (tmp_path / "taken" / "lines").write_text("x")
    odd = tmp_path / "odd\x01name"  # a frames folder whose name cannot be a sequence name
    odd.mkdir()
    (odd / "1.jpg").write_bytes((frames_dir / "0000.jpg").read_bytes())
    places = {"frames": frames_dir, "empty": tmp_path / "empty", "file": tmp_path / "file"}
    argv = [a.format(**places, taken=tmp_path / "taken", odd=odd) for a in argv]
    before = {p: p.stat().st_mtime_ns for p in tmp_path.rglob("*")}
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and match in err, err
    assert {p: p.stat().st_mtime_ns for p in tmp_path.rglob("*")} == before  # nothing written


def test_a_folder_of_frames_plays_in_number_order(tmp_path: Path) -> None:
    """1.jpg .. 12.jpg (TuSimple's naming) play 1, 2, ..., 12 — not 1, 10, 11, 12, 2, ... as plain sorting has it."""
    for i in range(1, 13):
        cv2.imwrite(str(tmp_path / f"{i}.png"), np.full((8, 8, 3), i, np.uint8))
    frames, count, _ = iter_frames(tmp_path)
    assert count == 12
    frames = list(frames)
    assert [int(image[0, 0, 0]) for _, image in frames] == list(range(1, 13))
    assert [name for name, _ in frames] == [f"{i}.png" for i in range(1, 13)]  # the names the frames are scored by


def test_a_failed_run_keeps_the_previous_results(checkpoint: Path, frames_dir: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "out"
    assert main([str(frames_dir), "--ckpt", str(checkpoint), "--out", str(out), "--no-video"]) == 0
    before = (out / "lanes.jsonl").read_bytes()
    bad = tmp_path / "bad.ckpt"
    bad.write_bytes(b"truncated")
    assert main([str(frames_dir), "--ckpt", str(bad), "--out", str(out), "--no-video"]) == 2
    assert "not a readable torch checkpoint" in capsys.readouterr().err
    assert (out / "lanes.jsonl").read_bytes() == before
    assert sorted(p.name for p in out.iterdir()) == sorted(["lanes.jsonl", OWNER_NAME])  # no temporary file left


def test_export_writes_onnx_and_prints_the_parity(checkpoint: Path, tmp_path: Path, capsys) -> None:
    from stamlane.cli import main as stamlane

    out = tmp_path / "model.onnx"
    assert (
        stamlane(["export", "--ckpt_path", str(checkpoint), "--output", str(out), "--streaming", str(tmp_path / "s")])
        == 0
    )
    said = capsys.readouterr().out
    assert (
        out.is_file()
        and (tmp_path / "s" / "encoder.onnx").is_file()
        and (tmp_path / "s" / "fuse_decode.onnx").is_file()
    )
    assert "T=2, 128x64, opset 17" in said  # WxH for people
    logits = float(said.split("max |logits| diff ")[1].split(",")[0])
    assert logits < 1e-4  # onnxruntime reproduces the PyTorch model
    assert not list(tmp_path.glob(".*tmp*"))  # no temporary file left


@pytest.mark.parametrize(
    ("extra", "match"),
    [
        (["--opset", "9"], "--opset must be in 16..21"),
        (["--output", "{ckpt}"], "would overwrite or write into the input"),
        (["--output", "{tmp}/model.txt"], "must end in .onnx"),
        (["--ckpt_path", "{tmp}/nowhere.ckpt"], "nowhere.ckpt: No such file or directory"),
        (["--streaming", "{ckpt}"], "would overwrite or write into the input"),
        (["--streaming", "{ckpt}/s"], "would overwrite or write into the input"),
    ],
)
def test_export_bad_input_is_one_line(checkpoint: Path, tmp_path: Path, capsys, extra: list[str], match: str) -> None:
    from stamlane.cli import main as stamlane

    extra = [a.format(ckpt=checkpoint, tmp=tmp_path) for a in extra]
    assert stamlane(["export", "--ckpt_path", str(checkpoint), *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert match in err and len(err.splitlines()) == 1
    bad = tmp_path / "bad.ckpt"
    bad.write_text("text")
    assert stamlane(["export", "--ckpt_path", str(bad)]) == 2
    assert "not a readable torch checkpoint" in capsys.readouterr().err


def test_the_device_is_checked_in_one_line(checkpoint: Path, frames_dir: Path, capsys: pytest.CaptureFixture) -> None:
    """``--device``: the network where the user asks (cpu here; the GPU path was run on an H200), a device this
    machine lacks answered in one line, exit status 2."""
    import torch

    from stamlane.stream.cli import build_parser, load_predictor

    argv = [str(frames_dir), "--ckpt", str(checkpoint)]
    assert load_predictor(build_parser().parse_args([*argv, "--device", "cpu"])).device == torch.device("cpu")
    for device, message in (("tpu9", "is not a device"), ("meta", "runs on cpu or cuda")):
        assert main([*argv, "--device", device]) == 2
        assert message in capsys.readouterr().err
    if not torch.cuda.is_available():
        assert main([*argv, "--device", "cuda"]) == 2
        assert "CUDA device(s)" in capsys.readouterr().err
