"""The oracles of the labels: key frame, aligned history, unaligned history (`stamlane.experiments.oracles`)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from stamlane_eval.io import read_tusimple

from stamlane.experiments.engine import oracle_subject
from stamlane.experiments.oracles import ORACLES, hist_from_key, oracle_predictions
from stamlane.experiments.split_scores import read_visibility
from stamlane.predict.postprocess import PostprocessConfig
from stamlane.synth.generator import REVEAL, SynthConfig, generate_clip


def test_hist_from_key_is_the_inverse_of_the_clips_exact_alignment(reveal_root: Path):
    geometry = json.loads((reveal_root / "homographies" / "reveal-0000.json").read_text())
    last_from_frame = np.asarray(geometry["last_from_frame"])
    for back in (1, 3, 7):
        h = hist_from_key(reveal_root, "clips/reveal-0000/12.jpg", back)
        product = h @ last_from_frame[11 - back]
        np.testing.assert_allclose(product / product[2, 2], np.eye(3), atol=1e-9)


def test_the_unaligned_oracle_moves_only_the_points_the_history_alone_shows(reveal_root: Path):
    gts = read_tusimple(reveal_root / "reveal.json")
    visibility = read_visibility(reveal_root, "reveal")
    found = oracle_predictions(gts, visibility, 4, PostprocessConfig(), (96, 160), root=reveal_root)
    assert tuple(found) == ORACLES
    differs = [a["lanes"] != b["lanes"] for a, b in zip(found["history"], found["unaligned"])]
    assert any(differs)  # the ego motion moves the revealed points where the history frame has them
    assert found["key"] != found["history"]  # and the history reveals points the key frame hides
    without_root = oracle_predictions(gts, visibility, 4, PostprocessConfig(), (96, 160))
    assert tuple(without_root) == ORACLES[:2] and without_root["history"] == found["history"]


def test_oracle_subjects_name_their_span():
    assert oracle_subject("key", 4) == "oracle:key"
    assert oracle_subject("history", 4) == "oracle:history-4f"
    assert oracle_subject("unaligned", 4) == "oracle:unaligned-4f"
    assert oracle_subject("history", 8, 2) == "oracle:history-8f-x2"


def test_the_reveal_ego_motion_moves_unaligned_lanes_twice_as_far_as_the_clean_clips():
    """Mean |x| between a key frame's lanes and those of the frame 3 back (the oldest of a 4-frame clip), unaligned:
    about 18 px at 640 px wide on reveal clips (a lane change in each), against about 9 on clean clips."""
    from stamlane.synth.generator import clip_statistics

    reveal = SynthConfig(**{k: v for k, v in REVEAL["key_flash"].overrides.items() if k != "key_occluder"})
    shifts = {}
    for name, config in (("reveal", reveal), ("clean", SynthConfig())):
        clips = [generate_clip(config, np.random.default_rng([9, 4, i])) for i in range(6)]
        shifts[name] = np.median([clip_statistics(c, 4)["unaligned_shift"] for c in clips])
    assert shifts["reveal"] > 1.5 * shifts["clean"] and shifts["reveal"] > 12, shifts
