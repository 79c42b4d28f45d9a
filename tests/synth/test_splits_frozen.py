"""The synthetic test and challenging splits are frozen: every result of the project is measured on them.

The generator may grow (new formats add files and training clips), but a change that moves one pixel or one label
of the clips the results were measured on makes old and new numbers incomparable. This test renders the first
test clips, one challenging clip of every factor and the first clean train and val clips with the default
settings and compares their frames (before JPEG) and labels with digests taken when format 4 was current (format
5 and 6 left them as they were). The label files of the default set (``data/synthetic-v6``) have the SHA-256 recorded in
docs/results.md: test.json ``0933b432...``, challenging.json ``cf5401b5...``.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import replace

import numpy as np
import pytest

from stamlane.synth.generator import SPLITS, SynthConfig, clip_kinds, generate_clip

FROZEN = {
    "test-0000": "0c811e28476326ea7b6475347c4a3c221682be28c892a7437924ee1aeba24d14",
    "test-0001": "9f57442b76b506fe092ad3c60965ce947f294183b93cec8a3e4dc99029600a46",
    "challenging-0000": "c52a3b705b8e1e404ed893f5e3b3cdcfcad18b3ef2599109bb4a8e8fd2dc3996",
    "challenging-0001": "2b38c7ebf0d5c293447d0bb2561d28cf935e30fd03bcf9c8326348256d0f59cb",
    "challenging-0002": "fd8f58ae508457214c35e4570eb8ab1eb886d488d5229ca7f4213fcb884b8b77",
    "challenging-0003": "4d1700a1de2fe5bc77fc70173854a0833eef5f5cb0ef99d81a9314031b333529",
    "challenging-0004": "7d6a9f3497d45de82981b3dad443045fe8b583f8d281b79e288a0d2c4411815e",
    "challenging-0005": "46006c620486eeaedfea7b3f15916304fcbbc83f811739c617008ab9b00629eb",
    "challenging-0006": "5274119e7a84e69f5d07bc33b5f592d1724d25aabfe3fa297e9c9e53787a8542",
    "challenging-0007": "9de744d1e399e83f5360bd9c2c8cbfa8e780ef40be173c66abf5fec74c31fe99",
    "train-0000": "290103c08ce52a2b509561fe6fb3d4d9086800af957c7d538c154dbbff577df8",
    "val-0000": "4560c59d2a3b0e33100ed2f93bde85e7134285c61831e0cf66e4bbb44800089e",
    "reveal-0000": "dfea54868445e7bc20456b9096a1d5520fdf77ae7716c9cdc010e5a5330466df",
    "reveal-0001": "b8f11fbb4679650895740c2fcec5ffde79c4d15d3e675892f9aa3c8cdda7f57a",
    "reveal-0002": "0cfe20cd3f5419cdcc09e34fd3d3ddb0e63bb4bb02ceebbc16d09916d3d0078f",
    "reveal-traffic-0000": "b4dcdd97c42616727719ad5ad2800aa5654ba71335d09139d918ffafd7c38f47",
    "reveal-traffic-0001": "e6543fb46e260906e5d2ddafcdf8ea58e7401be0e117f3e378a39f23b937b355",
}
"""SHA-256 of the frames (uint8 bytes, oldest first) and then the labels (json) of each clip; the reveal splits'
first clips of each kind frozen since format 6."""


@pytest.mark.parametrize("clip_id", sorted(FROZEN))
def test_a_frozen_clip_renders_to_the_same_pixels_and_labels(clip_id: str):
    split, index = clip_id.rsplit("-", 1)
    kind = clip_kinds(split, int(index), clean=1 << 30)  # no factor clips in the train and val splits here
    config = SynthConfig() if kind is None else replace(SynthConfig(), **kind[1].overrides)
    clip = generate_clip(config, np.random.default_rng([0, SPLITS.index(split), int(index)]))
    digest = hashlib.sha256()
    for frame in clip.frames:
        digest.update(frame.tobytes())
    digest.update(json.dumps(clip.labels).encode())
    assert digest.hexdigest() == FROZEN[clip_id], f"{clip_id} of the default set changed: results are not comparable"
