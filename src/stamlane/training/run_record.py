"""`RunRecord`: what a finished run records (its ``done.json`` in an experiment's run store), typed.

A record is read back from a file a user may have edited or copied: `RunRecord.from_json` checks every value
against the field's type (`RunRecord`'s annotations are the one table of types) and refuses a record that does not
fit, in one line (`RecordError`). Keys that are not fields are the settings the run shares with the other runs of
its experiment (data, steps, precision, recipe, ...), kept as they were written (`RunRecord.settings`): a record
written by an older stamlane loads as it is.
"""

from __future__ import annotations

import types
import typing
from dataclasses import MISSING, dataclass, field, fields
from pathlib import Path
from typing import Any

__all__ = ["RecordError", "RunRecord"]


class RecordError(ValueError):
    """A run record that does not fit `RunRecord` (a value of another type, a required value missing)."""


@dataclass
class RunRecord:
    """A finished run (see the module docstring).

    Attributes:
        run: the ``stamlane fit`` run folder (``config.yaml``, ``metrics.csv``, ``checkpoints/``).
        last_ckpt: its final weights.
        frames: its clip length (T).
        seed: its training seed.
        train_minutes: how long it trained (its last stage).
        hardware: the CPU or GPU, threads and torch version it trained on.
        pretrain_minutes: how long its stage 1 trained (two-stage recipes).
        last_ckpt_sha256: the SHA-256 of ``last_ckpt`` when it finished.
        recipe_args: whether the recipe's row arguments applied to it (records of before: True).
        scores: per ``<split>[@<probe>]`` the totals of its predictions.
        labels: per split the SHA-256 of the label file its predictions were scored against.
        frame_files: per split the digest of the frame files its predictions read.
        scoring: the rules its scores were made by.
        settings: what it shares with the other runs of its experiment (any other key of the record).
    """

    run: Path
    last_ckpt: Path
    frames: int
    seed: int
    train_minutes: float
    hardware: str | None = None
    pretrain_minutes: float | None = None
    last_ckpt_sha256: str | None = None
    recipe_args: bool = True
    scores: dict[str, Any] = field(default_factory=dict)
    labels: dict[str, str] = field(default_factory=dict)
    frame_files: dict[str, str] = field(default_factory=dict)
    scoring: str | None = None
    settings: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> RunRecord:
        """The record of a ``done.json``'s object (today's form or an older one).

        Raises:
            RecordError: a value of another type than its field's, a required value missing, ``frames`` below 1.
        """
        hints = typing.get_type_hints(cls)
        known = {f.name for f in fields(cls)} - {"settings"}
        values: dict[str, Any] = {}
        for f in fields(cls):
            if f.name == "settings":
                continue
            value: Any = data.get(f.name)
            required = f.default is MISSING and f.default_factory is MISSING
            if value is None and not required:
                continue
            if not _fits(hints[f.name], value) or (f.name == "frames" and value < 1):
                wanted = _wanted(hints[f.name]) + (" >= 1" if f.name == "frames" else "")
                raise RecordError(f"{f.name} must be {wanted}, got {value!r:.60}")
            values[f.name] = Path(value) if hints[f.name] is Path else value
        return cls(**values, settings={k: v for k, v in data.items() if k not in known})

    def to_json(self) -> dict[str, Any]:
        """The record as a ``done.json`` object: the settings, then every field that holds a value."""
        out = dict(self.settings)
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name != "settings" and value is not None and value != {}:
                out[f.name] = str(value) if isinstance(value, Path) else value
        return out

    def setting(self, key: str) -> Any:
        """The value of ``key``, a field or a setting (None when the record holds none)."""
        if key in {f.name for f in fields(self)} - {"settings"}:
            value = getattr(self, key)
            return str(value) if isinstance(value, Path) else value
        return self.settings.get(key)


def _arms(hint: Any) -> tuple[Any, ...]:
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        return typing.get_args(hint)
    return (hint,)


def _fits(hint: Any, value: Any) -> bool:
    """Whether a JSON value fits a field's type (a path is a string; a bool is no number)."""
    for arm in _arms(hint):
        base = typing.get_origin(arm) or arm
        if arm is type(None) and value is None:
            return True
        if arm is Any:
            return True
        if isinstance(value, bool):
            if base is bool:
                return True
            continue
        if arm is float and isinstance(value, (int, float)):
            return True
        if arm is Path and isinstance(value, str):
            return True
        if isinstance(base, type) and base is not Path and isinstance(value, base):
            return True
    return False


def _wanted(hint: Any) -> str:
    names = {Path: "str", float: "int or float", type(None): "null"}
    return " or ".join(names.get(a, getattr(typing.get_origin(a) or a, "__name__", str(a))) for a in _arms(hint))
