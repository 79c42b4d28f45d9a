"""TuSimple's own layout (``stamlane synth --layout tusimple``): TuSimple's folders, label files, key frames and
``h_samples``, read back by the TuSimple data module and aligned by ``stamlane align`` without ``--key-frames all``;
the frames are the generator layout's, and the generator layout's files are what they were."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from stamlane.align.cli import main as align_main
from stamlane.data.datamodule import ClipDataModule
from stamlane.data.options import ClipOptions, LoaderOptions
from stamlane.synth.cli import main as synth_main
from stamlane.synth.clip import generate_clip
from stamlane.synth.config import FACTORS, SynthConfig
from stamlane.synth.dataset import generate_dataset
from stamlane.synth.layout import SplitCounts
from stamlane.synth.tusimple_layout import TUSIMPLE_LABEL_FILES, clip_folder, label_file, tusimple_rows

SIZE, FRAMES = (96, 160), 9  # 9 frames: the generator layout labels frames 8 and 9 of train clips
SPLITS = {"train": 3, "val": 1, "test": 1, "challenging": 1}
PAPER_LABELS = {  # configs/tusimple_stam4.yaml's label files
    "train_labels": ["label_data_0313.json", "label_data_0601.json"],
    "val_labels": ["label_data_0531.json"],
    "test_labels": ["test_label.json"],
}


@pytest.fixture(scope="module")
def sets(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The same tiny set (seed 4) in both layouts."""
    config = SynthConfig(height=SIZE[0], width=SIZE[1], num_frames=FRAMES)
    out = {}
    for layout in ("stamlane", "tusimple"):
        out[layout] = root = tmp_path_factory.mktemp(layout)
        generate_dataset(root, SplitCounts(**SPLITS), seed=4, config=config, progress=False, layout=layout)
    return out


def _records(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines()]


def test_tusimple_rows_are_tusimple_s_at_720_and_scaled_elsewhere():
    assert tusimple_rows(720) == list(range(160, 720, 10))
    assert tusimple_rows(360) == list(range(80, 360, 5))
    assert tusimple_rows(SIZE[0])[0] == round(160 * SIZE[0] / 720) and tusimple_rows(SIZE[0])[-1] < SIZE[0]
    assert len(tusimple_rows(36)) < 56 and tusimple_rows(36) == sorted(set(tusimple_rows(36)))  # rounded, once
    with pytest.raises(ValueError, match="height must be >= 1"):
        tusimple_rows(0)


def test_folders_and_label_files_are_tusimple_s():
    assert clip_folder("tusimple", "train", 0) == "clips/0313-1/train-0000"
    assert clip_folder("tusimple", "train", 7) == "clips/0601/train-0007"
    assert clip_folder("tusimple", "val", 2) == "clips/0531/val-0002"
    assert clip_folder("tusimple", "test", 0) == "clips/0530/test-0000"
    assert clip_folder("tusimple", "challenging", 3) == "clips/challenging/challenging-0003"
    assert clip_folder("stamlane", "train", 7) == "clips/train-0007"
    assert (
        label_file("tusimple", "train", 1) == "label_data_0601.json" and label_file("stamlane", "val", 0) == "val.json"
    )
    assert set(TUSIMPLE_LABEL_FILES.values()) == {
        *PAPER_LABELS["train_labels"],
        "label_data_0531.json",
        "test_label.json",
    }
    with pytest.raises(ValueError, match="layout must be one of"):
        clip_folder("culane", "train", 0)


def test_the_set_is_in_tusimple_s_layout(sets: dict[str, Path]):
    root = sets["tusimple"]
    for name, split, clips in (
        ("label_data_0313.json", "train", [0, 2]),
        ("label_data_0601.json", "train", [1]),
        ("label_data_0531.json", "val", [0]),
        ("test_label.json", "test", [0]),
        ("challenging.json", "challenging", [0]),
    ):
        records = _records(root / name)
        # the last frame of each clip alone, at TuSimple's rows scaled to the frame height
        assert [r["raw_file"] for r in records] == [f"{clip_folder('tusimple', split, i)}/{FRAMES}.jpg" for i in clips]
        assert all(r["h_samples"] == tusimple_rows(SIZE[0]) for r in records)
        assert all(len(lane) == len(r["h_samples"]) for r in records for lane in r["lanes"])
        assert all(any(x >= 0 for x in lane) for r in records for lane in r["lanes"])
    assert sorted(p.name for p in (root / "clips/0313-1/train-0000").iterdir()) == sorted(
        f"{i}.jpg" for i in range(1, FRAMES + 1)
    )
    for name in ("train.json", "val.json", "test.json"):  # TuSimple's names replace the generator's
        assert not (root / name).exists()
    info = json.loads((root / "dataset.json").read_text())
    assert info["layout"] == "tusimple" and info["label_files"]["train"] == PAPER_LABELS["train_labels"]
    assert info["key_frames"]["train"] == [FRAMES] and info["key_frames"]["test"] == [FRAMES]
    frame_labels = json.loads((root / "frame_labels/train-0001.json").read_text())
    assert frame_labels[0]["raw_file"] == "clips/0601/train-0001/1.jpg"  # every frame's labels, in their folder


def test_the_frames_are_the_generator_layout_s_and_its_files_are_unchanged(sets: dict[str, Path]):
    a, b = sets["stamlane"], sets["tusimple"]
    for split, i in (("train", 1), ("val", 0), ("challenging", 0)):
        for n in (1, FRAMES):
            old = (a / clip_folder("stamlane", split, i) / f"{n}.jpg").read_bytes()
            assert (b / clip_folder("tusimple", split, i) / f"{n}.jpg").read_bytes() == old
    assert json.loads((b / "homographies/val-0000.json").read_text()) == json.loads(
        (a / "homographies/val-0000.json").read_text()
    )
    info = json.loads((a / "dataset.json").read_text())
    assert "layout" not in info and "label_files" not in info  # the generator layout's record as it was
    assert [r["raw_file"] for r in _records(a / "test.json")][-1] == f"clips/test-0000/{FRAMES}.jpg"
    assert len(_records(a / "train.json")) > 3  # several key frames per train clip (key step 1)


def test_at_720_rows_the_labels_are_the_generator_s_with_tusimple_s_rows_above():
    config = SynthConfig(height=720, width=1280, num_frames=2)
    own = generate_clip(config, np.random.default_rng([0, 2, 0]))
    tusimple = generate_clip(config, np.random.default_rng([0, 2, 0]), label_rows=tusimple_rows(720))
    assert tusimple.h_samples == list(range(160, 720, 10)) and own.h_samples[0] > 160
    assert all((x == y).all() for x, y in zip(own.frames, tusimple.frames))
    above = tusimple.h_samples.index(own.h_samples[0])
    for own_lanes, lanes in zip(own.labels, tusimple.labels):
        assert len(lanes) == len(own_lanes) > 0
        assert all(lane[above:] == o and set(lane[:above]) == {-2} for lane, o in zip(lanes, own_lanes))


def test_the_tusimple_data_module_reads_it_and_align_caches_its_key_frames(
    sets: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture
):
    root, cache = sets["tusimple"], tmp_path / "alignment"
    assert align_main([str(root), "--cache", str(cache), "--num-frames", "4", "--quiet"]) == 0  # no --key-frames
    capsys.readouterr()
    modules = {
        align: ClipDataModule(
            str(root),
            format="tusimple",
            clip=ClipOptions(num_frames=4, image_size=(64, 128), align=align, cache_dir=str(cache)),
            loader=LoaderOptions(batch_size=2, num_workers=0),
            **PAPER_LABELS,
        )
        for align in ("cache", "fly")
    }
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a key frame missing from the cache would be estimated with a warning
        for module in modules.values():
            module.setup("fit")
            module.setup("test")
        cached = modules["cache"].datasets
        assert {split: len(cached[split]) for split in ("train", "val", "test")} == {"train": 3, "val": 1, "test": 1}
        batch = next(iter(modules["cache"].train_dataloader()))
        assert tuple(batch["frames"].shape) == (2, 4, 3, 64, 128)
        sample, fly = cached["val"][0], modules["fly"].datasets["val"][0]
    assert sample["meta"]["raw_file"] == f"clips/0531/val-0000/{FRAMES}.jpg"
    np.testing.assert_allclose(sample["key_from_hist"], fly["key_from_hist"], atol=1e-4)
    assert not np.allclose(sample["key_from_hist"][0], np.eye(3), atol=1e-3)  # a real alignment, not the identity


def test_the_cli_writes_it_and_refuses_key_steps(tmp_path: Path, capsys: pytest.CaptureFixture):
    out = tmp_path / "t"
    argv = ["--out", str(out), "--clips", "3", "--size", "96x64", "--frames", "3", "--layout", "tusimple", "--quiet"]
    assert synth_main([*argv, "--challenging-clips", "0", "--reveal-clips", "0", "--reveal-traffic-clips", "0"]) == 0
    capsys.readouterr()
    assert [r["raw_file"] for r in _records(out / "label_data_0313.json")] == ["clips/0313-1/train-0000/3.jpg"]
    assert (out / "label_data_0601.json").read_text() == ""  # one train clip: TuSimple's second file is empty
    for extra, message in (
        (["--train-key-step", "1"], "--train-key-step must be 0, got 1"),
        (["--eval-key-step", "3"], "--eval-key-step must be 0, got 3"),
        (["--demo"], "drop --layout"),
    ):
        assert synth_main([*argv[:1], str(tmp_path / "u"), *argv[2:], *extra]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and message in err
        assert not (tmp_path / "u").exists()
    with pytest.raises(ValueError, match="key steps must be 0"):
        generate_dataset(tmp_path / "v", SplitCounts(train=1), layout="tusimple", train_key_step=1)


def test_a_small_set_has_a_clip_of_every_factor_by_default(tmp_path: Path, capsys: pytest.CaptureFixture):
    out = tmp_path / "s"
    argv = ["--out", str(out), "--clips", "3", "--size", "96x64", "--frames", "2", "--quiet"]
    assert synth_main([*argv, "--reveal-clips", "0", "--reveal-traffic-clips", "0"]) == 0
    capsys.readouterr()
    assert len(_records(out / "challenging.json")) == len(FACTORS)
    for factor in FACTORS:  # none of the per-factor files is empty
        assert len(_records(out / f"challenging-{factor}.json")) == 1, factor
