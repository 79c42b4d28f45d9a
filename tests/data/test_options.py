"""The data option groups: defaults, YAML lists read as tuples, one-line errors naming the value, what they build."""

from __future__ import annotations

import dataclasses

import pytest

from stamlane.data.corruption import DEFAULT_KINDS
from stamlane.data.datamodule import ClipDataModule
from stamlane.data.options import DEMO_SYNTH, GROUPS, AugmentOptions, ClipOptions, LoaderOptions, SynthOptions
from stamlane.synth.layout import DEMO_SPLITS, SplitCounts


def test_defaults_are_the_documented_ones() -> None:
    clip = ClipOptions()
    assert (clip.num_frames, clip.stride, clip.image_size, clip.crop_top) == (4, 1, (128, 256), 0.0)
    assert (clip.align, clip.warp, clip.align_strategy, clip.cache_dir, clip.horizon_row) == (
        "fly",
        "image",
        "chain",
        None,
        None,
    )
    augment = AugmentOptions()
    assert augment.crop_scale == (0.85, 1.0) and augment.flip_prob == 0.5
    assert (augment.brightness, augment.contrast, augment.saturation, augment.hue) == (0.2, 0.2, 0.2, 0.0)
    assert augment.key_corruption == 0.0 and augment.key_corruption_kinds == DEFAULT_KINDS
    synth = DEMO_SYNTH
    assert synth.splits().as_dict() == {
        "train": 120,
        "val": 20,
        "test": 100,
        "challenging": 128,
        "reveal": 90,
        "reveal_traffic": 60,
        "train_factors": 120,
        "val_factors": 32,
        "train_motion": 96,
    }
    assert (synth.train_key_step, synth.eval_key_step, synth.seed, synth.size) == (1, 3, 0, (360, 640))
    assert (synth.config().width, synth.config().height) == (640, 360)
    assert LoaderOptions() == LoaderOptions(batch_size=4, num_workers=0)
    assert set(GROUPS) == {"clip", "augment", "synth", "loader"}


def test_the_split_counts_are_those_of_split_counts_alone() -> None:
    """`SplitCounts` declares and checks the counts: each of its fields is a ``data.synth`` key, no other is a split."""
    names = [f.name for f in dataclasses.fields(SplitCounts)]
    assert [f.name for f in dataclasses.fields(SynthOptions)][: len(names)] == names
    assert SynthOptions().splits() == SplitCounts() and DEMO_SYNTH.splits() == DEMO_SPLITS
    assert SynthOptions(test=3, seed=5, size=(64, 96)).as_dict() == {**SplitCounts(test=3).as_dict()}
    assert SynthOptions(test=3).total() == 3
    assert ClipDataModule().synth == DEMO_SYNTH  # the demo's set when root is null


def test_yaml_lists_become_tuples_and_the_groups_are_frozen() -> None:
    clip = ClipOptions(image_size=[64, 128])  # as jsonargparse or a checkpoint's hyperparameters give it
    assert clip.image_size == (64, 128) and clip == ClipOptions(image_size=(64, 128))
    augment = AugmentOptions(crop_scale=[0.9, 1], key_corruption_kinds=["blank", "glare"])
    assert augment.crop_scale == (0.9, 1.0) and augment.key_corruption_kinds == ("blank", "glare")
    assert SynthOptions(size=[64, 96]).size == (64, 96)
    with pytest.raises(dataclasses.FrozenInstanceError):
        clip.num_frames = 2  # type: ignore[misc]


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: ClipOptions(num_frames=0), "num_frames must be >= 1, got 0"),
        (lambda: ClipOptions(stride=0), "stride must be >= 1, got 0"),
        (lambda: ClipOptions(image_size=(4, 64)), r"image_size must be \(H, W\) with sides >= 8, got \(4, 64\)"),
        (lambda: ClipOptions(image_size=(64, 128, 3)), "image_size must have two values"),
        (lambda: ClipOptions(crop_top=0.95), r"crop_top must be in \[0, 0.9\), got 0.95"),
        (lambda: ClipOptions(align="sideways"), "align must be one of .*'sideways'"),
        (lambda: ClipOptions(warp="pixels"), "warp must be one of .*'pixels'"),
        (lambda: ClipOptions(align_strategy="zigzag"), "align_strategy must be one of .*'zigzag'"),
        (lambda: AugmentOptions(flip_prob=3.0), r"flip_prob must be in \[0, 1\], got 3.0"),
        (lambda: AugmentOptions(crop_scale=(0.9, 0.5)), "crop_scale must satisfy"),
        (lambda: AugmentOptions(hue=0.7), "hue must be in"),
        (lambda: AugmentOptions(brightness=1.0), "brightness must be in"),
        (lambda: AugmentOptions(key_corruption=2.0), r"key corruption prob must be in \[0, 1\], got 2.0"),
        (lambda: AugmentOptions(key_corruption_kinds=("fog",)), "key corruption kinds must be some of"),
        (lambda: AugmentOptions(strides=(1, 0)), r"strides must all be >= 1, got \[1, 0\]"),
        (lambda: SynthOptions(train=-1), "synth: clip count of split 'train' must be an int >= 0, got -1"),
        (lambda: SynthOptions(reveal_traffic=2.5), "synth: clip count of split 'reveal_traffic' must be an int"),
        (lambda: SynthOptions(eval_key_step=-2), "synth.eval_key_step must be >= 0, got -2"),
        (lambda: SynthOptions(size=(0, 10)), r"synth.size must be \(H, W\) with positive sides, got \(0, 10\)"),
        (lambda: LoaderOptions(batch_size=0), "batch_size must be >= 1, got 0"),
        (lambda: LoaderOptions(num_workers=-1), "num_workers must be >= 0, got -1"),
    ],
)
def test_a_bad_value_fails_when_the_options_are_made(make, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        make()


def test_the_transforms_they_build() -> None:
    clip = ClipOptions(image_size=(80, 256), crop_top=0.4)
    evaluation = clip.transform()
    assert evaluation.image_size == (80, 256) and evaluation.crop_top == 0.4 and not evaluation.augments
    train = AugmentOptions().transform(clip)
    assert train.image_size == (80, 256) and train.crop_top == 0.4 and train.augments
    assert train.crop_scale == (0.85, 1.0) and train.flip_prob == 0.5 and train.brightness == 0.2
    assert AugmentOptions().corruption() is None
    corruption = AugmentOptions(key_corruption=0.5, key_corruption_kinds=("blank",)).corruption()
    assert corruption is not None and corruption.prob == 0.5 and corruption.kinds == ("blank",)
