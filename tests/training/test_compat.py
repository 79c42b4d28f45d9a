"""What older versions wrote is read in today's form: the flat data options of before the groups, the names of
classes before they moved (`stamlane.training.compat`)."""

from __future__ import annotations

from functools import partial
from pathlib import Path

import pytest
import yaml

from stamlane.data.options import GROUPS, ClipOptions
from stamlane.training.compat import (
    FLAT_KEYS,
    GROUPED_ONLY,
    RENAMED_CLASSES,
    OldOptionError,
    check_flags,
    clip_options,
    group_config,
    group_data,
    upgrade_config,
    upgrade_flags,
    upgrade_hparams,
)

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
    with pytest.raises(OldOptionError, match=r"data\.num_frames is 1 but data\.clip\.num_frames is 2"):
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
    assert upgrade_flags(old) == [
        "--data.augment.key_corruption=0.5",
        "--data.augment.key_corruption_kinds=[blank, glare]",
        "--data.root=x",
        "--data.clip.num_frames",
        "2",
    ]
    assert upgrade_flags(["--data.synth_size=[64, 96]"]) == ["--data.synth.size=[64, 96]"]
    check_flags(["--data.clip.num_frames=2", "--data.root=x", "--model.num_frames=2", "num_frames"])  # today's: fine
    with pytest.raises(OldOptionError, match=r"^--data.batch_size is now --data.loader.batch_size \(the data"):
        check_flags(["--data.root=x", "--data.batch_size=2"])
    # STAM's reading, formerly ``history``
    assert upgrade_flags(["--model.fusion.init_args.history=gates"]) == ["--model.fusion.init_args.reading=gates"]
    with pytest.raises(
        OldOptionError, match=r"^--model.fusion.init_args.history is now --model.fusion.init_args.reading"
    ):
        check_flags(["--model.fusion.init_args.history", "gates"])


# ------------------------------------------------------------------ renamed options (RENAMED_OPTIONS)
def test_stams_old_history_option_is_read_as_its_reading() -> None:
    old = {"fusion": {"class_path": "stamlane.models.STAM", "init_args": {"mode": "mixed", "history": "gates"}}}
    assert upgrade_hparams(old)["fusion"]["init_args"] == {"mode": "mixed", "reading": "gates"}
    same = {
        "fusion": {"class_path": "stamlane.models.stam.STAM", "init_args": {"history": "gates", "reading": "gates"}}
    }
    assert upgrade_hparams(same)["fusion"]["init_args"] == {"reading": "gates"}
    with pytest.raises(OldOptionError, match=r"fusion\.init_args\.history is 'gates' but fusion\.init_args\.reading"):
        upgrade_hparams({"fusion": {**same["fusion"], "init_args": {"history": "gates", "reading": "features"}}})
    other = {"fusion": {"class_path": "stamlane.models.STPSA", "init_args": {"history": "x"}}}
    assert upgrade_hparams(other) == other  # only the class that had the option
    config = upgrade_config(yaml.safe_load(FLAT_CONFIG.read_text()))  # the real config of before
    assert config["model"]["fusion"]["init_args"]["reading"] == "features"
    assert "history" not in config["model"]["fusion"]["init_args"]


# ------------------------------------------------------------------ names of before a move (RENAMED_CLASSES)
OLD_HPARAMS = {
    "encoder": {"class_path": "stamlane.models.VGGEncoder", "init_args": {"width": 0.125}},
    "fusion": {
        "class_path": "stamlane.models.STAM",
        "init_args": {"mode": "mixed", "reduction": 4, "history": "gates"},
    },
    "decoder": {"class_path": "stamlane.models.LaneDecoder", "init_args": {"embed_dim": 4}},
    "loss": {"class_path": "stamlane.losses.LaneLoss", "init_args": {"delta_v": 0.5}},
    "optimizer": "stamlane.module.paper_sgd",
    "scheduler": {"class_path": "stamlane.module.PolyLR", "init_args": {"power": 0.9}},
    "num_frames": 2,
    "image_size": [32, 64],
    "bf16": False,
    "_instantiator": "lightning.pytorch.cli.instantiate_module",
    "_class_path": "stamlane.module.StamLaneModule",
}
"""The hyper_parameters of a checkpoint written before the training shell moved into stamlane.training and before
STAM's ``history`` option was named ``reading``."""


def test_every_old_class_name_is_an_alias_of_todays_class() -> None:
    from stamlane.training.registry import registry

    table = registry()
    for old, new in RENAMED_CLASSES.items():
        assert old not in table or table[old] is table[new], old
    assert table["stamlane.losses.LaneLoss"] is table["stamlane.training.losses.LaneLoss"]
    assert table["stamlane.module.PolyLR"] is table["stamlane.training.module.PolyLR"]
    assert table["stamlane.module.paper_sgd"] is table["stamlane.training.module.paper_sgd"]


def test_names_are_upgraded_everywhere_and_nothing_else_changes() -> None:
    new = upgrade_hparams(OLD_HPARAMS)
    assert new["loss"] == {"class_path": "stamlane.training.losses.LaneLoss", "init_args": {"delta_v": 0.5}}
    assert new["optimizer"] == "stamlane.training.module.paper_sgd"
    assert new["scheduler"]["class_path"] == "stamlane.training.module.PolyLR"
    assert new["_class_path"] == "stamlane.training.module.StamLaneModule"
    assert new["fusion"]["init_args"] == {"mode": "mixed", "reduction": 4, "reading": "gates"}
    renamed = ("fusion", "loss", "optimizer", "scheduler", "_class_path")
    assert {k: v for k, v in new.items() if k not in renamed} == {
        k: v for k, v in OLD_HPARAMS.items() if k not in renamed
    }
    assert OLD_HPARAMS["loss"]["class_path"] == "stamlane.losses.LaneLoss"  # the input is not changed
    assert upgrade_hparams(new) == new  # today's: as it is
    callbacks = {"trainer": {"callbacks": [{"class_path": "stamlane.history_use.HistoryUseMonitor"}]}}
    assert upgrade_config(callbacks)["trainer"]["callbacks"][0]["class_path"] == (
        "stamlane.training.history_use_monitor.HistoryUseMonitor"
    )


def test_a_checkpoint_with_the_old_names_builds_the_same_network(tmp_path: Path) -> None:
    import torch

    from stamlane.models import STAM, LaneDecoder, VGGEncoder
    from stamlane.training.losses import LaneLoss
    from stamlane.training.module import StamLaneModule

    torch.manual_seed(0)
    net = StamLaneModule(
        VGGEncoder(width=0.125),
        partial(STAM, mode="mixed", reduction=4, reading="gates"),
        partial(LaneDecoder, embed_dim=4),
        loss=LaneLoss(delta_v=0.5),
        num_frames=2,
        image_size=(32, 64),
        bf16=False,
    ).eval()
    ckpt = tmp_path / "old.ckpt"
    torch.save({"state_dict": net.state_dict(), "hyper_parameters": OLD_HPARAMS}, ckpt)
    loaded = StamLaneModule.from_checkpoint(ckpt)  # through the closed registry, which refuses unknown names
    assert type(loaded.loss) is LaneLoss and loaded.loss.delta_v == 0.5
    assert loaded.net.fusion.reading == "gates"  # the old ``history: gates``
    assert loaded.hparams["loss"]["class_path"] == "stamlane.training.losses.LaneLoss"  # recorded in today's names
    clip = torch.rand(1, 2, 3, 32, 64)
    with torch.no_grad():
        for want, got in zip(net(clip), loaded(clip)):
            torch.testing.assert_close(got, want)


def test_a_run_config_with_the_old_names_is_read_in_todays(tmp_path: Path) -> None:
    from stamlane.training.registry import check_run_config, safe_config_file

    config = yaml.safe_load(FLAT_CONFIG.read_text())  # written before the groups and before the move
    assert config["model"]["loss"]["class_path"] == "stamlane.losses.LaneLoss"
    assert config["model"]["scheduler"]["class_path"] == "stamlane.module.PolyLR"
    text = yaml.safe_dump(config)
    checked = check_run_config(text, "old/config.yaml")
    assert checked["model"]["loss"]["class_path"] == "stamlane.training.losses.LaneLoss"
    assert checked["model"]["scheduler"]["class_path"] == "stamlane.training.module.PolyLR"
    assert checked["data"]["clip"]["num_frames"] == config["data"]["num_frames"]
    with safe_config_file(text, "old/config.yaml") as path:  # what LightningCLI reads: importable names only
        assert "stamlane.losses" not in path.read_text() and "stamlane.module." not in path.read_text()
