"""Reading what older stamlane versions wrote: the one place that knows their names.

Run folders (``config.yaml``), checkpoints (their ``hyper_parameters``, the run config and the
``datamodule_hyper_parameters`` they carry), experiment records and old ``--config`` files keep the names of the
version that wrote them. Each rename since is written once here, and everything that reads such a file upgrades it
through this module before anything else looks at it:

- `RENAMED_CLASSES`: classes that moved to another module (``stamlane.losses.LaneLoss`` is
  ``stamlane.training.losses.LaneLoss``); the closed registry takes the old names as aliases
  (`stamlane.training.registry.registry`) and `upgrade_names` writes today's;
- `RENAMED_OPTIONS` (and `RENAMED_FLAGS`, the same on the command line): options of a class that were renamed
  (``STAM(history=...)`` is ``STAM(reading=...)``);
- the flat data options: until the data options were grouped, every one was a plain argument of
  ``ClipDataModule`` (``data.num_frames``, ``data.flip_prob``, ``data.synth_train``, ``data.batch_size``);
  `group_data` turns such a ``data`` section into today's (``data.clip.num_frames``, ``data.augment.flip_prob``,
  ``data.synth.train``, ``data.loader.batch_size``). `FLAT_KEYS` is derived from the groups' fields, so that a new
  option is declared in its group alone.

Who upgrades: the closed registry for everything read from a checkpoint or a run folder (`upgrade_config`,
`upgrade_hparams`, `clip_options`), the experiment engine for the arguments its records hold (`upgrade_flags`),
and the YAML mode of ``stamlane fit|validate|test|predict`` (`yaml_mode`) for a ``--config`` file, which may be an
old run's ``config.yaml``. An old name typed on the command line is refused with today's (`check_flags`).
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from dataclasses import fields
from functools import cache
from typing import Any

from stamlane.data.options import GROUPS, ClipOptions

__all__ = [
    "CONFIG_MODE",
    "FLAT_KEYS",
    "RENAMED_CLASSES",
    "RENAMED_FLAGS",
    "RENAMED_OPTIONS",
    "OldOptionError",
    "check_flags",
    "clip_options",
    "group_config",
    "group_data",
    "upgrade_config",
    "upgrade_flags",
    "upgrade_hparams",
    "upgrade_names",
    "yaml_mode",
]

RENAMED_CLASSES: Mapping[str, str] = {
    # 0.1 -> the floors (docs/architecture.md): the Lightning shell moved into stamlane.training ...
    "stamlane.losses.LaneLoss": "stamlane.training.losses.LaneLoss",
    "stamlane.module.StamLaneModule": "stamlane.training.module.StamLaneModule",
    "stamlane.module.PolyLR": "stamlane.training.module.PolyLR",
    "stamlane.module.paper_sgd": "stamlane.training.module.paper_sgd",
    "stamlane.history_use.HistoryUseMonitor": "stamlane.training.history_use_monitor.HistoryUseMonitor",
    # ... and prediction into stamlane.predict
    "stamlane.predict.LanePredictionWriter": "stamlane.predict.prediction_writer.LanePredictionWriter",
}
"""Old dotted name of a class (or a function) a stored config may name -> today's."""

_STAM_READING = {"history": "reading"}  # STAM(history=) said which reading of the paper; "history" meant five things
RENAMED_OPTIONS: Mapping[str, Mapping[str, str]] = {
    "stamlane.models.STAM": _STAM_READING,
    "stamlane.models.stam.STAM": _STAM_READING,  # the defining module's name, which jsonargparse may write
}
"""Today's dotted name of a class -> {old name of an option of its ``init_args``: today's}."""
RENAMED_FLAGS: Mapping[str, str] = {"--model.fusion.init_args.history": "--model.fusion.init_args.reading"}
"""Old command-line option -> today's, for the options of `RENAMED_OPTIONS` where the configs set them (STAM is the
model's fusion)."""


class OldOptionError(ValueError):
    """An option of before that cannot be read as today's: given twice (old and new name, two values), a group that
    is not a mapping, or an old name on the command line. The message names today's option."""


def _flat_name(group: str, field: str) -> str:
    # the synthetic set's options were prefixed (synth_train, synth_size); the others kept their names
    return f"synth_{field}" if group == "synth" else field


GROUPED_ONLY = {("synth", "reveal"), ("synth", "reveal_traffic"), ("synth", "train_motion"), ("loader", "memory_mb")}
GROUPED_ONLY |= {("clip", "align_preset"), ("augment", "strides")}
"""Options added after the groups (generator format 6; the frame store; the alignment presets; the spacing mix): they
never had a flat name."""
FLAT_KEYS: dict[str, tuple[str, str]] = {
    _flat_name(group, f.name): (group, f.name)
    for group, cls in GROUPS.items()
    for f in fields(cls)
    if (group, f.name) not in GROUPED_ONLY
}
"""Each flat key of the old ``data`` section -> ``(group, field)`` of today's (``"synth_train"`` -> ``("synth",
"train")``). Options of a labelled dataset (``root``, ``format``, label files, ...) kept their place."""


def group_data(data: Mapping[str, Any]) -> dict[str, Any]:
    """A ``data`` section (a config's or a checkpoint's ``datamodule_hyper_parameters``) in today's grouped form.

    Flat keys move into their group; a value given both flat and grouped must be the same in both (a section
    holds one or the other); any other key is kept as it is. A section without flat keys comes back unchanged
    (as a new dict).

    Args:
        data: the section, flat, grouped or mixed.

    Returns:
        a new dict; the groups it touches are new dicts too (``data`` is not changed).

    Raises:
        OldOptionError: a value given flat and grouped with two different values (``data: {num_frames: 1,
            clip: {num_frames: 2}}``): which one was meant cannot be known.
    """
    out: dict[str, Any] = {}
    moved: dict[str, dict[str, Any]] = {}
    for key, value in data.items():
        if key in FLAT_KEYS:
            group, field = FLAT_KEYS[key]
            moved.setdefault(group, {})[field] = value
        else:
            out[key] = value
    for group, values in moved.items():
        given = dict(out[group]) if isinstance(out.get(group), Mapping) else {}
        for field, value in values.items():
            if field in given and given[field] != value:
                flat = _flat_name(group, field)
                raise OldOptionError(
                    f"data.{flat} is {value!r} but data.{group}.{field} is {given[field]!r}: give one of them"
                )
        out[group] = {**values, **given}
    return out


def group_config(config: Any) -> Any:
    """A whole config (the mapping a YAML file holds) with its ``data`` section grouped (`group_data`); anything
    else, or a config whose ``data`` is not a mapping (null, a file name), comes back as it is.

    Raises:
        OldOptionError: a group of the ``data`` section (``clip``, ``loader``, ...) that is not a mapping.
    """
    if isinstance(config, Mapping) and isinstance(config.get("data"), Mapping):
        data = config["data"]
        for group in GROUPS:  # a group given as a list or a number: one line here, not a TypeError when built
            if data.get(group) is not None and not isinstance(data[group], Mapping):
                raise OldOptionError(f"data.{group} must be a mapping of {group} options, got {data[group]!r}")
        if any(key in FLAT_KEYS for key in data):
            return {**config, "data": group_data(data)}
    return config


def clip_options(data: Mapping[str, Any]) -> ClipOptions:
    """How a run read its clips, from its ``data`` section or its checkpoint's ``datamodule_hyper_parameters``,
    flat or grouped (the defaults for what it does not say).

    Raises:
        ValueError: the clip options are not a mapping of `ClipOptions` fields with valid values.
    """
    clip = group_data(data).get("clip", {})
    if not isinstance(clip, Mapping):
        raise ValueError(f"data.clip must be a mapping of clip options, got {clip!r}")
    try:
        return ClipOptions(**clip)
    except TypeError as err:  # an unknown field, or a value of another type
        raise ValueError(f"data.clip {dict(clip)}: {err}") from None


_FLAG = re.compile(r"(--[\w.]+)(=.*)?", re.DOTALL)


def upgrade_flags(args: Iterable[str]) -> list[str]:
    """Command-line arguments in today's names: every flat ``--data.<key>[=value]`` in its group (``--data.
    num_frames=2`` -> ``--data.clip.num_frames=2``), every option of `RENAMED_FLAGS` renamed: how the arguments
    recorded by an older experiment read now."""
    out = []
    for arg in args:
        match = _FLAG.fullmatch(arg)
        if match:
            flag, value = match.group(1), match.group(2) or ""
            key = flag.removeprefix("--data.")
            if flag.startswith("--data.") and key in FLAT_KEYS:
                group, field = FLAT_KEYS[key]
                arg = f"--data.{group}.{field}{value}"
            elif flag in RENAMED_FLAGS:
                arg = f"{RENAMED_FLAGS[flag]}{value}"
        out.append(arg)
    return out


def check_flags(args: Iterable[str]) -> None:
    """Refuse old options on the command line (the flat data options, `RENAMED_FLAGS`), naming today's.

    Raises:
        OldOptionError: for the first old option.
    """
    for arg in args:
        renamed = upgrade_flags([arg])[0]
        if renamed != arg:
            old, new = arg.split("=", 1)[0], renamed.split("=", 1)[0]
            why = (
                "the data options are grouped: clip, augment, synth, loader" if old.startswith("--data.") else "renamed"
            )
            raise OldOptionError(f"{old} is now {new} ({why})")


def _renamed_keys(options: Mapping[str, Any], renamed: Mapping[str, str], where: str) -> dict[str, Any]:
    """``options`` with each old key of ``renamed`` under today's name; one given under both names must agree."""
    out = dict(options)
    for old, new in renamed.items():
        if old not in out:
            continue
        value = out.pop(old)
        if new in out and out[new] != value:
            raise OldOptionError(f"{where}.{old} is {value!r} but {where}.{new} is {out[new]!r}: give {new} alone")
        out.setdefault(new, value)
    return out


def upgrade_names(value: Any, where: str = "") -> Any:
    """A plain value (a config section, hyper_parameters) with today's names: every ``class_path`` and every string
    naming a class or a function of `RENAMED_CLASSES` renamed, the ``init_args`` of a class of `RENAMED_OPTIONS`
    with today's keys. A new value; ``value`` is not changed.

    Raises:
        OldOptionError: an option given under its old and its new name with two values.
    """
    if isinstance(value, str):
        return RENAMED_CLASSES.get(value, value)
    if isinstance(value, list):
        return [upgrade_names(item, f"{where}[{i}]") for i, item in enumerate(value)]
    if not isinstance(value, Mapping):
        return value
    out = {key: upgrade_names(item, f"{where}.{key}" if where else str(key)) for key, item in value.items()}
    class_path = out.get("class_path")
    renamed = RENAMED_OPTIONS.get(class_path) if isinstance(class_path, str) else None
    if renamed and isinstance(out.get("init_args"), Mapping):
        out["init_args"] = _renamed_keys(out["init_args"], renamed, f"{where}.init_args" if where else "init_args")
    return out


def upgrade_config(config: Any) -> Any:
    """A whole run config (the mapping a YAML file holds) in today's form: the ``data`` section grouped
    (`group_config`), classes and options renamed (`upgrade_names`). Anything that is not a mapping comes back as
    it is.

    Raises:
        OldOptionError: see `group_config` and `upgrade_names`.
    """
    return upgrade_names(group_config(config)) if isinstance(config, Mapping) else config


def upgrade_hparams(hparams: Any) -> Any:
    """A checkpoint's ``hyper_parameters`` (the options of ``StamLaneModule``, ``_class_path`` among them) with
    today's names (`upgrade_names`)."""
    return upgrade_names(hparams) if isinstance(hparams, Mapping) else hparams


CONFIG_MODE = "stamlane-yaml"
"""jsonargparse parser mode of ``stamlane fit|validate|test|predict`` (`yaml_mode`)."""


@cache
def yaml_mode() -> str:
    """`CONFIG_MODE`, registered with jsonargparse on the first call: YAML, every document read through
    `upgrade_config`, so that a ``--config`` written by an older version (an old run's ``config.yaml``, the flat
    data options, a moved class) is read in today's form."""
    import yaml
    from jsonargparse import get_loader, set_loader

    plain = get_loader("yaml")
    set_loader(CONFIG_MODE, lambda text: upgrade_config(plain(text)), exceptions=(yaml.YAMLError,))
    return CONFIG_MODE
