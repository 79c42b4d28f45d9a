"""The DataModule on a tiny generated synthetic set, and the ``synth`` / ``show`` tools."""

from __future__ import annotations

import importlib.util
import json
import warnings
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch

from stamlane.data import collate_clips
from stamlane.data.clips import mixed_stride
from stamlane.data.datamodule import DEFAULT_SYNTHETIC_ROOT, ClipDataModule
from stamlane.data.frame_store import DEFAULT_MEMORY_MB
from stamlane.data.labels import history_name
from stamlane.data.options import AugmentOptions, ClipOptions, LoaderOptions, SynthOptions
from stamlane.data.show_cli import main as show_main
from stamlane.synth.cli import main as synth_main
from stamlane.synth.config import SynthConfig, counts_of_total
from stamlane.synth.dataset import generate_dataset
from stamlane.synth.layout import SplitCounts

TINY_SYNTH = SynthOptions(
    train=2,
    val=1,
    test=1,
    challenging=0,
    train_factors=1,
    val_factors=0,
    reveal=0,
    reveal_traffic=0,
    train_motion=0,
    size=(64, 96),
)


def test_default_root_generates_the_synthetic_set_when_missing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    monkeypatch.chdir(tmp_path)
    dm = ClipDataModule(
        clip=ClipOptions(image_size=(32, 64), align="true"), synth=TINY_SYNTH, loader=LoaderOptions(batch_size=2)
    )
    dm.prepare_data()
    assert (tmp_path / DEFAULT_SYNTHETIC_ROOT / "dataset.json").is_file()
    # 20-frame clips: train key frames 8..20 (key step 1), the other splits 8, 11, 14, 17, 20 (key step 3)
    train_keys = (tmp_path / DEFAULT_SYNTHETIC_ROOT / "train.json").read_text().splitlines()
    assert len(train_keys) == 3 * 13 and json.loads(train_keys[0])["raw_file"] == "clips/train-0000/8.jpg"
    val_keys = [
        json.loads(r)["raw_file"] for r in (tmp_path / DEFAULT_SYNTHETIC_ROOT / "val.json").read_text().splitlines()
    ]
    assert val_keys == [f"clips/val-0000/{k}.jpg" for k in (8, 11, 14, 17, 20)]
    dm.setup("fit")
    batch = next(iter(dm.train_dataloader()))
    assert batch["frames"].shape == (2, 4, 3, 32, 64)
    assert batch["binary"].shape == (2, 32, 64) and batch["instance"].shape == (2, 32, 64)
    assert batch["key_from_hist"].shape == (2, 4, 3, 3)
    assert len(batch["lanes"]) == 2 and len(batch["meta"]) == 2
    assert batch["binary"].sum() > 0
    val = next(iter(dm.val_dataloader()))
    assert val["frames"].shape[0] == 2
    # the eval transform only resizes: net_from_orig is a pure scale of 64/96 x 32/64
    m = np.asarray(val["meta"][0]["net_from_orig"])
    assert abs(float(m[0, 0]) - 64 / 96) < 1e-9 and abs(float(m[1, 1]) - 32 / 64) < 1e-9
    assert next(iter(dm.predict_dataloader()))["frames"].shape[1] == 4
    # a second module finds the set and does not regenerate it
    before = (tmp_path / DEFAULT_SYNTHETIC_ROOT / "dataset.json").stat().st_mtime_ns
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # same settings: found silently
        ClipDataModule(synth=TINY_SYNTH).prepare_data()
    assert (tmp_path / DEFAULT_SYNTHETIC_ROOT / "dataset.json").stat().st_mtime_ns == before
    # a set recorded before a setting was added (label_lanes) had its default: found silently too
    info_path = tmp_path / DEFAULT_SYNTHETIC_ROOT / "dataset.json"
    info = json.loads(info_path.read_text())
    del info["config"]["label_lanes"]
    info_path.write_text(json.dumps(info))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ClipDataModule(synth=TINY_SYNTH).prepare_data()
    before = info_path.stat().st_mtime_ns
    with pytest.warns(UserWarning, match="other settings"):  # another size: kept, with a warning
        ClipDataModule(synth=replace(TINY_SYNTH, size=(64, 128))).prepare_data()
    assert (tmp_path / DEFAULT_SYNTHETIC_ROOT / "dataset.json").stat().st_mtime_ns == before


def test_datamodule_on_a_given_root(synthetic_root: Path):
    dm = ClipDataModule(
        root=str(synthetic_root),
        clip=ClipOptions(num_frames=2, stride=3, image_size=(32, 48), align="none"),
        loader=LoaderOptions(batch_size=3),
        test_labels=["test.json", "challenging.json"],
    )
    dm.setup("test")
    batch = next(iter(dm.test_dataloader()))
    assert batch["frames"].shape == (2, 2, 3, 32, 48)
    assert batch["meta"][1]["raw_file"] == "clips/challenging-0000/8.jpg"
    assert batch["meta"][0]["frame_paths"] == ["clips/test-0000/5.jpg", "clips/test-0000/8.jpg"]


def test_a_spacing_mix_reads_each_training_key_frame_at_one_stride_and_the_other_splits_at_the_clip_stride(
    tmp_path: Path,
):
    splits = SplitCounts(train=3, val=1)
    config = SynthConfig(width=160, height=96, num_frames=16)  # key frames 8-16 of each clip
    generate_dataset(tmp_path, splits, seed=3, config=config, train_key_step=1, eval_key_step=1, progress=False)

    def frame_paths(split: str) -> dict[str, list[str]]:
        dm = ClipDataModule(
            root=str(tmp_path),
            clip=ClipOptions(num_frames=3, stride=1, image_size=(32, 48), align="none", repeat_missing_history=True),
            augment=AugmentOptions(strides=[1, 3]),
        )
        dataset = dm.make_dataset(split)
        return {entry.raw_file: entry.frame_paths for entry in dataset.entries}

    train = frame_paths("train")
    seen = set()
    for key, paths in train.items():
        stride, number = mixed_stride(key, (1, 3)), int(Path(key).stem)
        backs = [2 * stride, stride, 0]
        for i in (1, 0):  # a frame before frame 1 is missing: the next later one stands in
            backs[i] = backs[i] if number - backs[i] >= 1 else backs[i + 1]
        assert paths == [history_name(key, back) for back in backs], key
        seen.add(stride)
    assert len(train) == 27 and seen == {1, 3}, "both spacings in the mix"
    assert frame_paths("train") == train, "the same stride for a key frame every time"
    for key, paths in frame_paths("val").items():
        assert paths == [history_name(key, back) for back in (2, 1, 0)]


@pytest.mark.skipif(importlib.util.find_spec("stamlane.align.homography") is None, reason="stamlane.align absent")
def test_on_the_fly_alignment_is_close_to_the_true_one(tmp_path: Path):
    cfg = SynthConfig(width=640, height=360, num_frames=2, occluder_prob=0.0)
    generate_dataset(tmp_path, SplitCounts(test=1), seed=11, config=cfg, progress=False)
    fly, true = (
        ClipDataModule(str(tmp_path), clip=ClipOptions(2, 1, (48, 80), align=align), loader=LoaderOptions(1))
        for align in ("fly", "true")
    )
    fly.setup("test")
    true.setup("test")
    a = fly.datasets["test"][0]["key_from_hist"][0].double().numpy()
    b = true.datasets["test"][0]["key_from_hist"][0].double().numpy()
    # key-frame road points mapped back into the history frame by both estimates
    road = np.array([[160, 250, 1], [480, 250, 1], [600, 350, 1], [40, 350, 1], [320, 200, 1]], dtype=np.float64).T
    pa, pb = np.linalg.inv(a) @ road, np.linalg.inv(b) @ road
    err = np.abs(pa[:2] / pa[2] - pb[:2] / pb[2]).max()
    assert err < 3.0, (err, fly.datasets["test"].aligner.failures)


@pytest.mark.skipif(importlib.util.find_spec("stamlane.align.cache") is None, reason="stamlane.align absent")
def test_cached_alignment_is_read_and_missing_pairs_are_estimated(synthetic_root: Path, tmp_path: Path):
    from stamlane.align import Alignment
    from stamlane.align.cache import alignment_to_json, cache_file, write_cache

    m = np.array([[1.0, 0, 3], [0, 1, 0], [0, 0, 1]])
    path = cache_file(tmp_path, synthetic_root, synthetic_root / "clips/test-0000")
    write_cache(path, {"8.jpg": {"7.jpg": alignment_to_json(Alignment(m, 30, 20, True, ""))}})
    from stamlane.data import TuSimpleClips

    ds = TuSimpleClips(
        synthetic_root,
        "test.json",
        clip=ClipOptions(num_frames=2, image_size=(32, 48), align="cache", cache_dir=tmp_path),
    )
    np.testing.assert_allclose(ds[0]["key_from_hist"][0].numpy(), m, atol=1e-6)
    ds3 = TuSimpleClips(
        synthetic_root,
        "test.json",
        clip=ClipOptions(num_frames=3, image_size=(32, 48), align="cache", cache_dir=tmp_path),
    )
    with pytest.warns(UserWarning, match="no entry"):
        k = ds3[0]["key_from_hist"].numpy()
    np.testing.assert_allclose(k[1], m, atol=1e-6)  # cached pair used, the missing one estimated
    assert k.shape == (3, 3, 3)


def test_datamodule_rejects_bad_options():
    with pytest.raises(ValueError, match="format"):
        ClipDataModule(format="kitti")
    with pytest.raises(ValueError, match="history_source"):
        ClipDataModule(history_source="shuffled")
    with pytest.raises(ValueError, match="train_labels must be given"):
        ClipDataModule(root=".", format="culane").make_dataset("train")


def test_a_datamodule_made_in_python_stores_plain_hyperparameters(tmp_path: Path):
    from stamlane.training.compat import clip_options

    dm = ClipDataModule(clip=ClipOptions(num_frames=2), loader=LoaderOptions(batch_size=3))
    loader = {"batch_size": 3, "num_workers": 0, "memory_mb": DEFAULT_MEMORY_MB}
    assert dm.hparams["clip"]["num_frames"] == 2 and dm.hparams["loader"] == loader
    assert dm.hparams_initial["clip"] == dm.hparams["clip"]  # what the loggers write
    torch.save({"datamodule_hyper_parameters": dict(dm.hparams)}, tmp_path / "h.ckpt")  # as a checkpoint holds them
    stored = torch.load(tmp_path / "h.ckpt", weights_only=True)["datamodule_hyper_parameters"]  # no dataclass
    assert clip_options(stored) == dm.clip  # how `stamlane stream` reads them back


def test_collate_rejects_mixed_shapes():
    a = {
        "frames": torch.zeros(2, 3, 8, 8),
        "binary": torch.zeros(8, 8),
        "instance": torch.zeros(8, 8),
        "key_from_hist": torch.zeros(2, 3, 3),
        "lanes": [],
        "meta": {},
    }
    b = dict(a, frames=torch.zeros(3, 3, 8, 8))
    assert collate_clips([a, a])["frames"].shape == (2, 2, 3, 8, 8)
    with pytest.raises(ValueError, match="share the clip shape"):
        collate_clips([a, b])
    with pytest.raises(ValueError, match="empty"):
        collate_clips([])


def test_history_names():
    assert history_name("clips/a/b/20.jpg", 3) == "clips/a/b/17.jpg"
    assert history_name("clips/a/b/10.jpg", 1) == "clips/a/b/9.jpg"
    assert history_name("d/v.MP4/00030.jpg", 30) == "d/v.MP4/00000.jpg"
    assert history_name("d/v.MP4/00030.jpg", 60) is None
    assert history_name("x/frame.jpg", 1) is None


def test_synth_tool_writes_a_set(tmp_path: Path, capsys: pytest.CaptureFixture):
    ten, two = counts_of_total(10), counts_of_total(2)
    assert (ten.train, ten.val, ten.test) == (8, 1, 1) and (two.train, two.val, two.test) == (2, 0, 0)
    out = tmp_path / "s"
    assert (
        synth_main(
            [
                "--out",
                str(out),
                "--clips",
                "3",
                "--challenging-clips",
                "1",
                "--size",
                "96x64",
                "--frames",
                "5",
                "--quiet",
            ]
        )
        == 0
    )
    assert "frames/s" in capsys.readouterr().out
    assert (out / "clips/train-0000/5.jpg").is_file() and (out / "challenging.json").is_file()
    assert cv2.imread(str(out / "clips/val-0000/1.jpg")).shape == (64, 96, 3)


@pytest.mark.parametrize(
    "argv",
    [
        ["--out", "x", "--clips", "0"],
        ["--out", "x", "--size", "big"],
        ["--clips", "3"],
        ["--out", "x", "--size", "8x8"],
    ],
)
def test_synth_tool_bad_input_is_one_line_and_status_2(argv: list[str], capsys: pytest.CaptureFixture):
    assert synth_main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err


def test_synth_never_writes_over_a_set_and_show_never_into_the_data(
    synthetic_root: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    before = (synthetic_root / "train.json").read_bytes()
    assert synth_main(["--out", str(synthetic_root), "--clips", "3", "--quiet"]) == 2
    assert "already holds a set" in capsys.readouterr().err
    assert (synthetic_root / "train.json").read_bytes() == before
    frame = synthetic_root / "clips" / "train-0000" / "1.jpg"
    picture = frame.read_bytes()
    argv = ["--root", str(synthetic_root), "--labels", "train.json", "--out", str(frame), "--size", "80x48"]
    assert show_main(argv) == 2
    err = capsys.readouterr().err
    assert "would overwrite or write into the input" in err and err.count("\n") == 1
    assert frame.read_bytes() == picture


def test_show_tool_writes_a_grid(synthetic_root: Path, tmp_path: Path, capsys: pytest.CaptureFixture):
    out = tmp_path / "grid.png"
    assert (
        show_main(
            [
                "--root",
                str(synthetic_root),
                "--labels",
                "train.json",
                "--out",
                str(out),
                "--n",
                "2",
                "--size",
                "80x48",
                "--align",
                "true",
            ]
        )
        == 0
    )
    img = cv2.imread(str(out))
    assert img.shape[0] == 2 * (48 + 4) and img.shape[1] == 5 * (80 + 4)  # 2 rows of 4 frames + the target tile
    assert show_main(["--root", str(tmp_path / "nope"), "--labels", "x.json", "--out", str(out)]) == 2
    assert show_main(["--root", str(synthetic_root), "--labels", "train.json", "--out", str(out), "--size", "x"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 2 and "Traceback" not in err
