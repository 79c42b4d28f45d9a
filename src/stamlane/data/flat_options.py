"""The flat data options of configs and checkpoints written before the groups of `stamlane.data.options`.

Until the data options were grouped, every one was a plain argument of ``ClipDataModule``: ``data.num_frames``,
``data.flip_prob``, ``data.synth_train``, ``data.batch_size``. Run folders (``config.yaml``), checkpoints (the
config and ``datamodule_hyper_parameters`` they carry) and experiment records made then still hold that form;
`group_data` turns such a ``data`` section into today's (``data.clip.num_frames``, ``data.augment.flip_prob``,
``data.synth.train``, ``data.loader.batch_size``). `FLAT_KEYS` is derived from the groups' fields, so that a
new option is declared in its group alone.

Every config ``stamlane fit|validate|test|predict`` reads goes through `group_config` (`stamlane.lightning_cli`);
an old flat option on the command line is refused with its new name (`check_flags`).
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from dataclasses import fields
from typing import Any

from stamlane.data.options import GROUPS, ClipOptions

__all__ = ["FLAT_KEYS", "FlatOptionError", "check_flags", "clip_options", "group_config", "group_data", "group_flags"]


def _flat_name(group: str, field: str) -> str:
    # the synthetic set's options were prefixed (synth_train, synth_size); the others kept their names
    return f"synth_{field}" if group == "synth" else field


GROUPED_ONLY = {("synth", "reveal"), ("synth", "reveal_traffic"), ("synth", "train_motion")}
"""Options added after the groups (generator format 6): they never had a flat name."""
FLAT_KEYS: dict[str, tuple[str, str]] = {
    _flat_name(group, f.name): (group, f.name)
    for group, cls in GROUPS.items()
    for f in fields(cls)
    if (group, f.name) not in GROUPED_ONLY
}
"""Each flat key of the old ``data`` section -> ``(group, field)`` of today's (``"synth_train"`` -> ``("synth",
"train")``). Options of a labelled dataset (``root``, ``format``, label files, ...) kept their place."""


class FlatOptionError(ValueError):
    """An old flat data option where only today's are read (the command line): the message names the new one."""


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
        FlatOptionError: a value given flat and grouped with two different values (``data: {num_frames: 1,
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
                raise FlatOptionError(
                    f"data.{flat} is {value!r} but data.{group}.{field} is {given[field]!r}: give one of them"
                )
        out[group] = {**values, **given}
    return out


def group_config(config: Any) -> Any:
    """A whole config (the mapping a YAML file holds) with its ``data`` section grouped (`group_data`); anything
    else, or a config whose ``data`` is not a mapping (null, a file name), comes back as it is.

    Raises:
        FlatOptionError: a group of the ``data`` section (``clip``, ``loader``, ...) that is not a mapping.
    """
    if isinstance(config, Mapping) and isinstance(config.get("data"), Mapping):
        data = config["data"]
        for group in GROUPS:  # a group given as a list or a number: one line here, not a TypeError when built
            if data.get(group) is not None and not isinstance(data[group], Mapping):
                raise FlatOptionError(f"data.{group} must be a mapping of {group} options, got {data[group]!r}")
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


_FLAG = re.compile(r"--data\.(\w+)(=.*)?", re.DOTALL)


def group_flags(args: Iterable[str]) -> list[str]:
    """Command-line arguments with every flat ``--data.<key>[=value]`` renamed to its grouped form (``--data.
    num_frames=2`` -> ``--data.clip.num_frames=2``): how the arguments recorded by an older experiment read now."""
    out = []
    for arg in args:
        match = _FLAG.fullmatch(arg)
        if match and match.group(1) in FLAT_KEYS:
            group, field = FLAT_KEYS[match.group(1)]
            arg = f"--data.{group}.{field}{match.group(2) or ''}"
        out.append(arg)
    return out


def check_flags(args: Iterable[str]) -> None:
    """Refuse old flat data options on the command line, naming the new one.

    Raises:
        FlatOptionError: for the first ``--data.<flat key>``.
    """
    for arg in args:
        renamed = group_flags([arg])[0]
        if renamed != arg:
            old, new = arg.split("=", 1)[0], renamed.split("=", 1)[0]
            raise FlatOptionError(f"{old} is now {new} (the data options are grouped: clip, augment, synth, loader)")
