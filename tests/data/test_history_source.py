"""What fills the history slots: the clip's own frames, copies of its key frame, or another clip's history; and
the training-time corruption of the key frame alone."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from stamlane.data import DataError, TuSimpleClips
from stamlane.data.corruption import KeyFrameCorruption
from stamlane.data.options import ClipOptions
from tests.data.conftest import write_image

SIZE = (32, 48)


@pytest.fixture
def two_clips(tusimple_root: Path) -> Path:
    """The TuSimple fixture with clip 200's frames made different from clip 100's (grey 250 - 5 n)."""
    for n in range(1, 21):
        write_image(tusimple_root / "clips" / "0313-1" / "200" / f"{n}.jpg", value=250 - 5 * n)
    return tusimple_root


def _frames(root: Path, source: str) -> list[torch.Tensor]:
    ds = TuSimpleClips(
        root, "label_data.json", clip=ClipOptions(num_frames=4, image_size=SIZE, align="none"), history_source=source
    )
    return [ds[i]["frames"] for i in range(len(ds))]


def test_key_copies_the_key_frame_into_every_slot(two_clips: Path):
    real, key = _frames(two_clips, "real"), _frames(two_clips, "key")
    for r, k in zip(real, key):
        assert torch.equal(k[-1], r[-1])  # the key frame is the key frame
        assert all(torch.equal(k[t], r[-1]) for t in range(3))  # and so is every history slot
        assert not torch.equal(r[0], r[-1])  # (which the real history is not)


def test_other_clip_takes_the_history_of_another_clip_and_keeps_the_key_frame(two_clips: Path):
    ds = TuSimpleClips(
        two_clips,
        "label_data.json",
        clip=ClipOptions(num_frames=4, image_size=SIZE, align="none"),
        history_source="other_clip",
    )
    assert [ds.partner(i) for i in range(len(ds))] == [1, 0]
    real, other = _frames(two_clips, "real"), _frames(two_clips, "other_clip")
    for i, j in ((0, 1), (1, 0)):
        assert torch.equal(other[i][-1], real[i][-1])
        assert torch.equal(other[i][:-1], real[j][:-1])
    sample = ds[0]
    assert sample["meta"]["history_source"] == "other_clip"
    assert sample["meta"]["raw_file"] == "clips/0313-1/100/20.jpg"  # labels and targets stay the key frame's
    assert sample["binary"].sum() > 0


def test_other_clip_needs_two_clips_and_unknown_sources_are_refused(tusimple_root: Path):
    (tusimple_root / "one.json").write_text((tusimple_root / "label_data.json").read_text().splitlines()[0] + "\n")
    ds = TuSimpleClips(
        tusimple_root,
        "one.json",
        clip=ClipOptions(num_frames=4, image_size=SIZE, align="none"),
        history_source="other_clip",
    )
    with pytest.raises(DataError, match="needs samples of two clips"):
        ds[0]
    with pytest.raises(ValueError, match="history_source must be one of"):
        TuSimpleClips(
            tusimple_root, "label_data.json", clip=ClipOptions(image_size=SIZE, align="none"), history_source="shuffled"
        )


def test_key_corruption_changes_the_key_frame_only():
    rng = np.random.default_rng(0)
    clip = rng.uniform(0.2, 0.6, (4, 3, 40, 64)).astype(np.float32)
    for kind in ("drop", "glare", "occluder", "blank"):
        out = KeyFrameCorruption(1.0, (kind,))(clip.copy(), np.random.default_rng(1))
        np.testing.assert_array_equal(out[:-1], clip[:-1])
        assert np.abs(out[-1] - clip[-1]).mean() > 0.01, kind
        assert out.min() >= 0 and out.max() <= 1
    untouched = KeyFrameCorruption(0.0)(clip.copy(), np.random.default_rng(1))
    np.testing.assert_array_equal(untouched, clip)
    with pytest.raises(ValueError, match="prob must be in"):
        KeyFrameCorruption(1.5)
    with pytest.raises(ValueError, match="kinds must be some of"):
        KeyFrameCorruption(0.5, ("rain",))


def test_key_corruption_reaches_training_samples_only(tusimple_root: Path):
    corrupt = KeyFrameCorruption(1.0, ("drop",))
    plain = TuSimpleClips(
        tusimple_root, "label_data.json", clip=ClipOptions(num_frames=2, image_size=SIZE, align="none")
    )
    spoilt = TuSimpleClips(
        tusimple_root,
        "label_data.json",
        clip=ClipOptions(num_frames=2, image_size=SIZE, align="none"),
        key_corruption=corrupt,
    )
    a, b = (
        plain.load(plain.entries[0], np.random.default_rng(3)),
        spoilt.load(spoilt.entries[0], np.random.default_rng(3)),
    )
    assert torch.equal(a["frames"][0], b["frames"][0]) and not torch.equal(a["frames"][1], b["frames"][1])
    assert torch.equal(a["binary"], b["binary"])  # the targets are the undamaged frame's


def _synthetic_frames(root: Path, source: str, align: str) -> torch.Tensor:
    ds = TuSimpleClips(
        root, "reveal.json", clip=ClipOptions(num_frames=4, image_size=(48, 80), align=align), history_source=source
    )
    return ds[0]["frames"]


@pytest.mark.parametrize("source", ["warped_key", "reversed"])
def test_matched_null_and_reversed_history_leave_the_key_frame_unchanged(reveal_root: Path, source: str):
    for align in ("true", "none"):
        real, probed = _synthetic_frames(reveal_root, "real", align), _synthetic_frames(reveal_root, source, align)
        assert torch.equal(probed[-1], real[-1])  # the key frame's pixels, exactly
        assert not torch.equal(probed[:-1], real[:-1])


def test_reversed_history_is_the_clips_own_frames_in_reverse_order(reveal_root: Path):
    real, reversed_ = (_synthetic_frames(reveal_root, s, "none") for s in ("real", "reversed"))
    assert torch.equal(reversed_[:-1], real[:-1].flip(0))


def test_matched_null_brings_back_the_key_frames_own_pixels_with_wedges(reveal_root: Path):
    """Warped out through the exact homography and aligned back, each history slot shows the key frame (blurred by
    two resamplings) where it has content, and black where the key frame had none: no new content."""
    null = _synthetic_frames(reveal_root, "warped_key", "true")
    key = null[-1]
    for slot in null[:-1]:
        inside = slot.sum(0) > 0.05  # outside: the black wedge a real warped history frame has too
        assert inside.float().mean() > 0.5
        assert (slot - key).abs().sum(0)[inside].median() < 0.1
    copied = _synthetic_frames(reveal_root, "key", "true")
    assert not torch.equal(null[:-1], copied[:-1])  # unlike the key copy, it carries the warp's blur and wedges
