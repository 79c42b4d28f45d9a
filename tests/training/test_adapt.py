"""``stamlane adapt``: pseudo-labels kept where a clip agrees over the ground plane, a real run end to end, bad input."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
import torch

from stamlane.cli import main
from stamlane.data.layouts import TuSimpleClips
from stamlane.data.options import ClipOptions
from stamlane.data.transforms import net_homographies
from stamlane.predict.pseudo_labels import (
    IGNORE,
    PseudoLabelConfig,
    clip_pseudo_labels,
    consistent_labels,
    warp_probability,
)
from stamlane.synth.config import SynthConfig
from stamlane.synth.dataset import generate_dataset
from stamlane.synth.layout import SplitCounts
from stamlane.training.adapt import ADAPT_KEY, AdaptConfig, real_loss

SIZE = (80, 256)  # the shipped dashcam models' network input (H, W)
FOUR = ClipOptions(num_frames=4, image_size=SIZE, align="true")  # the generator's exact homographies


@pytest.fixture(scope="module")
def drive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One 20-frame dashcam clip of the generator (640x360), every frame from the 8th labelled."""
    root = tmp_path_factory.mktemp("drive")
    generate_dataset(
        root, SplitCounts(train=1), seed=5, config=SynthConfig(world="dashcam3", label_lanes="adjacent"), progress=False
    )
    return root


# ----------------------------------------------------------------------------------- the consistency rule
def test_consistent_labels_by_hand() -> None:
    key = np.zeros((6, 8), np.float32)
    key[:, 2] = 0.9  # a lane every frame sees
    key[:, 6] = 0.9  # a lane one history frame alone agrees with
    key[0, 4] = 0.5  # uncertain: neither lane nor background
    hist = np.zeros((3, 6, 8), np.float32)
    hist[:, :, 2] = 0.95
    hist[0, :, 6] = 0.95
    hist[1, 3, 0] = np.nan  # a pixel that frame does not see: no vote
    labels = consistent_labels(key, hist, PseudoLabelConfig(hi=0.7, lo=0.1, min_agree=2, tolerance_px=0))
    assert (labels[:, 2] == 1).all()
    assert (labels[:, 6] == IGNORE).all()  # one history frame of three: not enough
    assert labels[0, 4] == IGNORE
    assert labels[3, 0] == 0 and (labels[:, 0] == 0).all()
    assert labels[2, 7] == 0 and (labels[:, 5] == 0).all()
    # a history lane one pixel beside the key frame's: agreement within the tolerance, and no background next to it
    shifted = np.roll(hist, 1, axis=2)
    near = consistent_labels(key, shifted, PseudoLabelConfig(min_agree=2, tolerance_px=1))
    assert (near[:, 2] == 1).all()
    assert (near[:, 4] != 0).all()  # the shifted lane (column 3) spreads to column 4: not background
    exact = consistent_labels(key, shifted, PseudoLabelConfig(min_agree=2, tolerance_px=0))
    assert (exact[:, 2] == IGNORE).all()
    # min_agree 0: the key frame's confidence alone
    alone = consistent_labels(key, hist[:0], PseudoLabelConfig(min_agree=0))
    assert (alone[:, 6] == 1).all()


def test_warp_marks_what_a_frame_does_not_see() -> None:
    prob = np.ones((10, 20), np.float32)
    shift = np.array([[1.0, 0, 5], [0, 1, 0], [0, 0, 1]])
    warped = warp_probability(prob, shift)
    assert np.isnan(warped[:, :5]).all() and (warped[:, 6:] == 1).all()
    with pytest.raises(ValueError, match="3x3"):
        warp_probability(prob, np.eye(2))
    with pytest.raises(ValueError, match="lo < hi"):
        PseudoLabelConfig(hi=0.2, lo=0.5)


def _clips(root: Path) -> tuple[TuSimpleClips, dict[str, int]]:
    data = TuSimpleClips(root, "train.json", clip=FOUR)
    return data, {entry.raw_file: i for i, entry in enumerate(data.entries)}


def test_a_lane_is_kept_where_the_clip_agrees_and_dropped_where_a_frame_disagrees(drive: Path) -> None:
    """Each frame's "probability" is its own label mask; the exact ground homographies of the generator carry the
    history's masks onto the key frame, where they must agree with its lanes."""
    data, position = _clips(drive)
    key = data[len(data) - 1]  # frame 20: frames 17-19 before it, all labelled
    index = [position[p] for p in key["meta"]["frame_paths"]]
    probs = np.stack([data[i]["binary"].numpy().astype(np.float32) for i in index])
    homs = net_homographies(key["key_from_hist"].numpy(), np.asarray(key["meta"]["net_from_orig"]))
    config = PseudoLabelConfig(hi=0.7, lo=0.1, min_agree=2, tolerance_px=1)
    labels = clip_pseudo_labels(probs, homs, config)
    lane = probs[-1] > 0.5
    assert lane.sum() > 100
    assert (labels[lane] == 1).mean() > 0.8  # the key frame's lanes: kept where the history agrees
    assert (labels[~lane] != 1).all()  # nothing else called lane
    assert (labels == 0).mean() > 0.8  # most of the road: background
    # without the alignment, the history's lanes land beside the key frame's as the camera moves: fewer kept
    unaligned = clip_pseudo_labels(probs, np.repeat(np.eye(3)[None], 4, axis=0), config)
    assert (unaligned[lane] == 1).sum() < (labels[lane] == 1).sum()

    # a lane that two of the three history frames do not draw (a flickering detection): dropped, not background
    right = np.zeros_like(lane)
    right[:, SIZE[1] // 2 :] = True
    flicker = probs.copy()
    for j in (0, 1):
        warped_right = cv2.warpPerspective(right.astype(np.float32), np.linalg.inv(homs[j]), SIZE[::-1]) > 0.5
        flicker[j][warped_right] = 0.0
    dropped = clip_pseudo_labels(flicker, homs, config)
    assert (dropped[lane & right] == 1).mean() < 0.05
    assert (dropped[lane & right] == 0).mean() < 0.05  # the key frame saw it: ignored, never background
    assert (dropped[lane & ~right] == 1).mean() > 0.8  # the other lanes as before

    # a line the key frame alone draws (a false detection): no history frame agrees, ignored
    strips = [c for c in range(SIZE[1] - 3) if (labels[40:, c : c + 3] == 0).all()]
    assert strips  # a strip of road every frame calls background
    ghost = probs.copy()
    ghost[-1][40:, strips[0] : strips[0] + 3] = 1.0
    ghosted = clip_pseudo_labels(ghost, homs, config)
    assert (ghosted[40:, strips[0] : strips[0] + 3] == IGNORE).all()


def test_the_loss_on_pseudo_labels_ignores_the_ignored() -> None:
    logits = torch.zeros(1, 2, 4, 4, requires_grad=True)
    labels = torch.full((1, 4, 4), IGNORE, dtype=torch.int64)
    assert float(real_loss(logits, labels).detach()) == 0.0
    labels[0, 0, 0] = 1
    loss = real_loss(logits, labels)
    loss.backward()
    assert logits.grad is not None
    assert torch.count_nonzero(logits.grad[0, :, 1:, :]) == 0  # only the labelled pixel
    with pytest.raises(ValueError, match="steps"):
        AdaptConfig(steps=0)


# ----------------------------------------------------------------------------------- the command
def _video(frames: list[Path], path: Path) -> Path:
    first = cv2.imread(str(frames[0]))
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 10.0, (first.shape[1], first.shape[0]))
    for frame in frames:
        writer.write(cv2.imread(str(frame)))
    writer.release()
    return path


@pytest.fixture(scope="module")
def drive_video(drive: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = drive / "clips" / "train-0000"
    frames = sorted(folder.glob("*.jpg"), key=lambda p: int(p.stem))
    return _video(frames, tmp_path_factory.mktemp("video") / "drive.mp4")


def _error(capsys: pytest.CaptureFixture[str]) -> str:
    lines = [line for line in capsys.readouterr().err.splitlines() if line.startswith("stamlane adapt:")]
    assert len(lines) == 1, lines
    return lines[0]


def test_adapt_writes_a_checkpoint_that_predict_opens(
    drive: Path, drive_video: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "adapted"
    args = ["--out", str(out), "--steps", "3", "--synthetic", str(drive), "--min-lane-pixels", "20", "--threads", "1"]
    assert main(["adapt", "--ckpt_path", "stam4-dashcam", "--source", str(drive_video), *args, "--no-progress"]) == 0
    ckpt = out / "adapted.ckpt"
    content = torch.load(ckpt, map_location="cpu", weights_only=True)
    record = content[ADAPT_KEY]
    assert record["settings"]["steps"] == 3 and record["source"] == "drive.mp4"
    assert 0 < record["pseudo_labels"]["kept"] <= record["pseudo_labels"]["with_history"] == 17
    from stamlane.weights import shipped_path

    before = torch.load(shipped_path("stam4-dashcam"), map_location="cpu", weights_only=True)["state_dict"]
    after = content["state_dict"]
    assert before.keys() == after.keys()
    changed = [k for k in before if before[k].is_floating_point() and not torch.equal(before[k], after[k])]
    assert any(k.startswith("net.fusion.") for k in changed) and any(k.startswith("net.encoder.") for k in changed)
    head = [k for k in before if k.startswith("net.decoder.embedding_head.") and k.endswith("weight")]
    assert head and all(torch.equal(before[k], after[k]) for k in head)  # the embedding head stays as it was
    assert (out / "adapt.json").is_file()
    capsys.readouterr()
    predicted = tmp_path / "predicted"
    flags = ["--predictions.output_dir", str(predicted), "--trainer.enable_progress_bar=false"]
    assert main(["predict", "--ckpt_path", str(ckpt), "--source", str(drive_video), *flags]) == 0
    assert (predicted / "predictions.json").is_file() or any(predicted.rglob("*.txt"))


def test_adapt_refuses_bad_input_in_one_line(
    drive: Path, drive_video: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    common = ["--ckpt_path", "stam4-dashcam", "--steps", "1", "--no-progress"]
    assert main(["adapt", *common, "--source", str(tmp_path / "missing.mp4"), "--out", str(tmp_path / "o")]) == 2
    assert "does not exist" in _error(capsys)
    frames = sorted((drive / "clips" / "train-0000").glob("*.jpg"), key=lambda p: int(p.stem))
    short = _video(frames[:6], tmp_path / "short.mp4")
    assert main(["adapt", *common, "--source", str(short), "--out", str(tmp_path / "o")]) == 2
    assert "needs at least" in _error(capsys)
    assert main(["adapt", *common, "--source", str(drive_video), "--out", str(drive_video.parent)]) == 2
    assert "beside the input" in _error(capsys)
    folder = drive / "clips" / "train-0000"
    assert main(["adapt", *common, "--source", str(folder), "--out", str(folder / "out")]) == 2
    assert "input" in _error(capsys)
    assert main(["adapt", *common, "--source", str(drive_video), "--out", str(drive_video)]) == 2
    _error(capsys)
    assert main(["adapt", *common, "--source", str(drive_video), "--steps", "0"]) == 2
    assert "--steps" in _error(capsys)
    assert not (tmp_path / "o").exists() and not (folder / "out").exists()
    assert sorted(p.name for p in drive_video.parent.iterdir()) == ["drive.mp4"]
