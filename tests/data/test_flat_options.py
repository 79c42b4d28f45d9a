"""The flat data options of configs and checkpoints written before the groups: read in today's grouped form."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from stamlane.data.flat_options import (
    FLAT_KEYS,
    GROUPED_ONLY,
    FlatOptionError,
    check_flags,
    clip_options,
    group_config,
    group_data,
    group_flags,
)
from stamlane.data.options import GROUPS, ClipOptions

FLAT_CONFIG = Path(__file__).with_name("flat_demo_config.yaml")
"""A real config of before the groups (``--print_config`` of configs/demo.yaml at 5a179c8)."""


def test_every_old_data_option_has_its_place() -> None:
    flat = yaml.safe_load(FLAT_CONFIG.read_text())["data"]
    kept = {"root", "format", "train_labels", "val_labels", "test_labels", "predict_labels", "label_dir"}
    kept |= {"thickness", "on_error", "history_source"}  # a labelled dataset's: plain arguments still
    assert set(flat) - kept == set(FLAT_KEYS)  # every other flat option moved, and nothing else is claimed
    assert len(FLAT_KEYS) == sum(len(cls.__dataclass_fields__) for cls in GROUPS.values()) - len(GROUPED_ONLY) == 30
    # the renamed ones, written out (FLAT_KEYS is derived from the groups' fields)
    assert FLAT_KEYS["num_frames"] == ("clip", "num_frames") and FLAT_KEYS["crop_top"] == ("clip", "crop_top")
    assert FLAT_KEYS["flip_prob"] == ("augment", "flip_prob")
    assert FLAT_KEYS["key_corruption_kinds"] == ("augment", "key_corruption_kinds")
    assert FLAT_KEYS["synth_train"] == ("synth", "train") and FLAT_KEYS["synth_size"] == ("synth", "size")
    assert FLAT_KEYS["batch_size"] == ("loader", "batch_size")


def test_a_flat_config_is_grouped_value_for_value() -> None:
    old = yaml.safe_load(FLAT_CONFIG.read_text())
    new = group_config(old)
    assert new["model"] == old["model"] and new["trainer"] == old["trainer"]  # only the data section changes
    for key, value in old["data"].items():
        if key in FLAT_KEYS:
            group, field = FLAT_KEYS[key]
            assert new["data"][group][field] == value, key
            assert key not in new["data"]
        else:
            assert new["data"][key] == value, key
    assert new["data"]["clip"] == {
        "num_frames": 4,
        "stride": 1,
        "image_size": [80, 256],
        "crop_top": 0.4,
        "align": "fly",
        "warp": "image",
        "cache_dir": None,
        "horizon_row": None,
        "align_strategy": "chain",
        "repeat_missing_history": False,
    }
    assert old["data"]["num_frames"] == 4  # the input is not changed
    assert group_config(new) == new  # grouped already: as it is
    for other in (None, "text", [1, 2], {"data": None}, {"data": "data.yaml"}, {"model": {"num_frames": 4}}):
        assert group_config(other) == other


def test_a_value_given_flat_and_grouped_must_agree_and_other_keys_stay() -> None:
    mixed = {"root": "r", "num_frames": 3, "clip": {"num_frames": 3, "stride": 2}, "_instantiator": "x"}
    assert group_data(mixed) == {"root": "r", "clip": {"num_frames": 3, "stride": 2}, "_instantiator": "x"}
    with pytest.raises(FlatOptionError, match=r"data\.num_frames is 1 but data\.clip\.num_frames is 2"):
        group_data({"num_frames": 1, "clip": {"num_frames": 2}})  # which was meant cannot be known: refused


def test_clip_options_from_a_checkpoint_of_either_form() -> None:
    flat_hparams = {"num_frames": 2, "image_size": [64, 128], "horizon_row": 100, "crop_top": 0.25, "root": "x"}
    grouped_hparams = {"root": "x", "clip": {"num_frames": 2, "image_size": [64, 128], "horizon_row": 100}}
    want = ClipOptions(num_frames=2, image_size=(64, 128), horizon_row=100)
    assert clip_options(flat_hparams) == ClipOptions(num_frames=2, image_size=(64, 128), horizon_row=100, crop_top=0.25)
    assert clip_options(grouped_hparams) == want
    assert clip_options({}) == ClipOptions()
    with pytest.raises(ValueError, match=r"data\.clip must be a mapping"):
        clip_options({"clip": "fly"})
    with pytest.raises(ValueError, match="unexpected keyword argument 'frames'"):
        clip_options({"clip": {"frames": 2}})
    with pytest.raises(ValueError, match="num_frames must be >= 1"):
        clip_options({"num_frames": 0})


def test_flags_are_renamed_for_records_and_refused_on_the_command_line() -> None:
    old = [
        "--data.key_corruption=0.5",
        "--data.key_corruption_kinds=[blank, glare]",
        "--data.root=x",
        "--data.num_frames",
        "2",
    ]
    assert group_flags(old) == [
        "--data.augment.key_corruption=0.5",
        "--data.augment.key_corruption_kinds=[blank, glare]",
        "--data.root=x",
        "--data.clip.num_frames",
        "2",
    ]
    assert group_flags(["--data.synth_size=[64, 96]"]) == ["--data.synth.size=[64, 96]"]
    check_flags(["--data.clip.num_frames=2", "--data.root=x", "--model.num_frames=2", "num_frames"])  # today's: fine
    with pytest.raises(FlatOptionError, match=r"^--data.batch_size is now --data.loader.batch_size \(the data"):
        check_flags(["--data.root=x", "--data.batch_size=2"])
