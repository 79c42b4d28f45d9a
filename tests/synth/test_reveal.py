"""The reveal splits: 12-frame clips whose occluder is in the key frame alone, and traffic at 5 fps; the frozen
splits unchanged beside them."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from stamlane.synth.clip import generate_clip
from stamlane.synth.config import REVEAL, REVEAL_TRAFFIC, SynthConfig
from stamlane.synth.dataset import generate_dataset
from stamlane.synth.layout import FORMAT_VERSION, REVEAL_FRAMES, SPLITS, SplitCounts
from stamlane.synth.visibility import visibility_class

SMALL = SynthConfig(width=160, height=96)
SPAN = 4
"""The demo models' clip length at stride 1: none of its history frames may carry the key frame's occluder."""


def _reveal_clip(kind: str, index: int, config: SynthConfig = SMALL):
    return generate_clip(replace(config, **REVEAL[kind].overrides), np.random.default_rng([0, 4, index]))


def _occluded_frames(clip, kind: str) -> list[int]:
    """The frames (0-based) that carry the occluder: opaque kinds in the occluder mask (the reveal clips have no
    vehicles), the flash as a frame much brighter than the first."""
    if kind == "key_flash":
        base = clip.frames[0].mean()
        return [i for i, f in enumerate(clip.frames) if f.mean() > base + 40]
    return [i for i, m in enumerate(clip.vehicle_masks) if m.any()]


@pytest.mark.parametrize("kind", list(REVEAL))
def test_a_reveal_clip_has_its_occluder_in_the_key_frame_alone(kind: str):
    for index in range(3):
        clip = _reveal_clip(kind, index)
        assert len(clip.frames) == REVEAL_FRAMES
        occluded = _occluded_frames(clip, kind)
        assert occluded == [REVEAL_FRAMES - 1], f"{kind} clip {index}: occluder in frames {occluded}"
        history = range(REVEAL_FRAMES - SPAN, REVEAL_FRAMES - 1)
        assert not set(occluded) & set(history)


def test_the_check_sees_an_occluder_that_reaches_into_the_history():
    clip = _reveal_clip("key_spray", 0, replace(SMALL, key_occluder_frames=2))
    assert _occluded_frames(clip, "key_spray") == [REVEAL_FRAMES - 2, REVEAL_FRAMES - 1]


def test_the_opaque_occluders_hide_labelled_points_and_bad_kinds_are_refused():
    hidden = 0
    for kind in ("key_spray", "key_blobs"):
        clip = _reveal_clip(kind, 1)
        hidden += sum(sum(lane) for lane in clip.occluded[-1])
        assert not any(any(lane) for lane in clip.occluded[-2])
    assert hidden > 0
    with pytest.raises(ValueError, match="key_occluder must be one of"):
        SynthConfig(key_occluder="rain")
    with pytest.raises(ValueError, match="key_occluder_frames"):
        SynthConfig(key_occluder="spray", key_occluder_frames=0)


def test_reveal_splits_name_their_kinds_and_see_over_every_history_frame(reveal_root: Path):
    info = json.loads((reveal_root / "dataset.json").read_text())
    assert info["format_version"] == FORMAT_VERSION
    assert info["visibility_reach"]["reveal"] == REVEAL_FRAMES - 1
    kinds = [info["clip_factors"][f"reveal-{i:04d}"] for i in range(6)]
    assert kinds == [*REVEAL, *REVEAL]
    traffic = [info["clip_factors"][f"reveal-traffic-{i:04d}"] for i in range(4)]
    assert traffic == [*REVEAL_TRAFFIC, *REVEAL_TRAFFIC]
    for kind in REVEAL:
        lines = (reveal_root / f"reveal-{kind}.json").read_text().splitlines()
        assert [json.loads(r)["raw_file"].split("/")[-1] for r in lines] == ["12.jpg"] * 2
    masks = [json.loads(line)["visibility"] for line in (reveal_root / "visibility" / "reveal.json").open()]
    classes = [visibility_class(m, SPAN) for image in masks for lane in image for m in lane if m >= 0]
    assert classes.count("revealed") > 0.1 * len(classes)  # the history shows what the key frame hides


def test_reveal_clips_leave_every_other_split_as_it_was(tmp_path: Path):
    splits = {"train": 1, "val": 1, "test": 1, "challenging": 1}
    plain = generate_dataset(
        tmp_path / "a", SplitCounts(**splits), seed=2, config=SMALL, progress=False, visibility=False
    )
    more = generate_dataset(
        tmp_path / "b",
        SplitCounts(**splits | dict(reveal=3, train_motion=1)),
        seed=2,
        config=SMALL,
        progress=False,
        visibility=False,
    )
    assert SPLITS[-2:] == ("reveal", "reveal-traffic")  # the new splits' seeds come after the old ones'
    for name in ("test.json", "challenging.json", "val.json", "clips/test-0000/20.jpg", "clips/train-0000/20.jpg"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes(), name
    assert more["clip_factors"]["train-0001"] == "motion" and "train-0001" not in plain["clip_factors"]
    assert (tmp_path / "b" / "clips" / "train-0001" / "12.jpg").is_file()


def test_synth_writes_the_reveal_splits_by_default_and_refuses_negative_counts(tmp_path: Path, capsys):
    from stamlane.synth.cli import main

    out = tmp_path / "set"
    args = ["--out", str(out), "--clips", "3", "--size", "96x64", "--quiet", "--challenging-clips", "0"]
    assert main([*args, "--reveal-clips", "3", "--reveal-traffic-clips", "2", "--train-motion", "1"]) == 0
    info = json.loads((out / "dataset.json").read_text())
    assert (
        info["splits"]["reveal"] == 3 and info["splits"]["reveal_traffic"] == 2 and info["splits"]["train_motion"] == 1
    )
    assert len((out / "reveal.json").read_text().splitlines()) == 3
    assert (out / "visibility" / "reveal-traffic.json").is_file()
    assert main(["--out", str(tmp_path / "bad"), "--train-motion", "-1"]) == 2
    assert capsys.readouterr().err.strip() == "stamlane synth: --train-motion must be >= 0, got -1"


def test_synth_demo_writes_the_set_the_data_options_generate():
    from stamlane.data.options import DEMO_SYNTH
    from stamlane.synth.layout import DEMO_SPLITS, EVAL_KEY_STEP, TRAIN_KEY_STEP

    options = DEMO_SYNTH
    assert options.splits() == DEMO_SPLITS
    assert (options.train_key_step, options.eval_key_step, options.seed) == (TRAIN_KEY_STEP, EVAL_KEY_STEP, 0)
    assert options.config() == SynthConfig()
