"""``SynthConfig.label_lanes``: the labels of TuSimple's convention (the ego lane's marks and those of the lanes beside
it) on the same frames as every mark's labels."""

from __future__ import annotations

import json

import numpy as np
import pytest

from stamlane.synth.clip import generate_clip
from stamlane.synth.config import SynthConfig

SMALL = SynthConfig(width=320, height=180, num_frames=2, world="dashcam3")


def _pair(seed: int) -> tuple:
    every = generate_clip(SMALL, np.random.default_rng(seed))
    adjacent = generate_clip(SynthConfig(**{**SMALL.__dict__, "label_lanes": "adjacent"}), np.random.default_rng(seed))
    return every, adjacent


def test_adjacent_labels_keep_the_marks_nearest_the_camera_on_the_same_frames():
    dropped = 0
    for seed in range(12):
        every, adjacent = _pair(seed)
        assert all(np.array_equal(a, b) for a, b in zip(every.frames, adjacent.frames))  # the labels alone differ
        for lanes, kept in zip(every.labels, adjacent.labels):
            assert len(kept) <= 4  # within two lane widths either side: four marks at most
            assert kept, "the ego lane's marks are always labelled"
            start = lanes.index(kept[0])  # a run of the marks, left to right: the ones beyond it were left out
            assert lanes[start : start + len(kept)] == kept
            if len(kept) < len(lanes):
                dropped += 1
                # on the lowest row any mark reaches, the marks left out lie further from the image's centre column
                bottom = max(i for lane in lanes for i, x in enumerate(lane) if x != -2)
                centre = SMALL.width / 2
                far = [abs(lane[bottom] - centre) for lane in lanes if lane not in kept and lane[bottom] != -2]
                near = [abs(lane[bottom] - centre) for lane in kept if lane[bottom] != -2]
                assert not far or not near or min(far) > max(near)
    assert dropped > 0, "some of these roads have five marks, or four with the camera in an outer lane"


def test_every_mark_is_labelled_by_default_and_a_bad_choice_is_refused():
    assert SynthConfig().label_lanes == "all"
    with pytest.raises(ValueError, match="label_lanes must be one of"):
        SynthConfig(label_lanes="nearest")


def test_stamlane_synth_label_lanes_adjacent(tmp_path, capsys):
    from stamlane.synth.cli import main as synth_main

    small = ["--clips", "1", "--challenging-clips", "0", "--reveal-clips", "0", "--reveal-traffic-clips", "0"]
    args = [*small, "--size", "128x72", "--frames", "9", "--quiet", "--world", "dashcam3"]
    assert synth_main(["--out", str(tmp_path / "a"), *args, "--label-lanes", "adjacent"]) == 0
    info = json.loads((tmp_path / "a" / "dataset.json").read_text())
    assert info["config"]["label_lanes"] == "adjacent"
    assert synth_main(["--out", str(tmp_path / "b"), *args, "--label-lanes", "nearest"]) == 2
    assert "--label-lanes" in capsys.readouterr().err
