"""The run store: where an experiment keeps its runs and predictions, and the one way a run is declared finished.

`RunStore` is the one place that spells the layout of an experiment's folder ``<out>``::

    <out>/<row>-s<seed>/done.json                   the run's record, written last (`RunStore.mark`)
    <out>/<row>-s<seed>/run/                        the ``stamlane fit`` run: config.yaml, metrics.csv,
                                                    checkpoints/last.ckpt (the final weights)
    <out>/predictions/<row>-s<seed>/<split>         its predictions of a split (predictions.json, per_image.jsonl
                                                    or per_clip.jsonl, overlays/)
    <out>/predictions/<row>-s<seed>/<split>@<probe> the same with its history probed (``key``, ``other_clip``, ...)
    <out>/predictions/oracle-<kind>-<T>f/<split>    an oracle of the labels
    <out>/summary.json, tables.md, ...              what the command writes at the top

A run is finished when its folder holds ``done.json``, written last and atomically, with the settings it was made
with and the SHA-256 of its final checkpoint. `RunStore.finished` is the resume lock: a record made with other
settings is refused (another ``--out`` is needed); a record that does not parse, names files outside the
experiment's folder or whose checkpoint no longer matches its digest (a tampered or half-copied folder) is refused
too, each with one line (`ExperimentError`). A record written by an older stamlane is read in today's form first
(`upgrade_record`).

A record is a `stamlane.training.run_record.RunRecord` (its fields and their types: ``seed``, ``train_minutes``,
``run``, ``last_ckpt``, ``frames``, ``hardware``, ``recipe_args``, once scored ``scores``, ``labels``, ``frame_files``
and ``scoring``); the settings are its other keys. ``frame_files`` is per split the digest of its frame files
(`stamlane.experiments.runner.frame_files_digest`): a record written before the frames were digested has none, and
its predictions stand for the frames found when it is next scored.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import yaml

from stamlane.safety.budget import MAX_RECORD_BYTES
from stamlane.safety.guard import GuardError, file_sha256, read_inside, write_atomic
from stamlane.training.run_record import RecordError, RunRecord

__all__ = ["DONE", "ExperimentError", "RunStore", "upgrade_record"]

DONE = "done.json"
RUN = "run"
"""The ``stamlane fit`` run folder inside a run's folder (the logger's version)."""
PREDICTIONS = "predictions"


class ExperimentError(Exception):
    """A known failure of an experiment (bad rows, a used ``--out``, a broken run folder): one line, exit 2."""


def upgrade_record(record: dict[str, Any]) -> dict[str, Any]:
    """A run record as today's stamlane writes it: the ``stamlane fit`` arguments it was made with (``row_args``,
    ``pretrain_args``, ``extra``) in today's names (a run recorded with ``--data.key_corruption`` before the data
    options were grouped is the same run as one with ``--data.augment.key_corruption``), the recipe's own
    (``row_args``, ``pretrain_args``) with their values written as `stamlane.training.runs.flags_of` writes them
    (`_as_flags_write`: ``[blank, glare]`` of before is ``["blank", "glare"]``, the same option), and
    ``pretrain_args`` empty where the record is of before recipes took stage-1 arguments (there were none)."""
    from stamlane.training.compat import upgrade_flags

    upgraded = record | {"pretrain_args": record.get("pretrain_args", [])}
    upgraded |= {k: upgrade_flags(upgraded[k]) for k in ("row_args", "pretrain_args", "extra") if _flags(upgraded, k)}
    return upgraded | {k: _as_flags_write(upgraded[k]) for k in ("row_args", "pretrain_args") if _flags(upgraded, k)}


def _flags(record: dict[str, Any], key: str) -> bool:
    return isinstance(record.get(key), list) and all(isinstance(arg, str) for arg in record[key])


def _as_flags_write(args: list[str]) -> list[str]:
    """Recorded ``--key=value`` arguments with each value as `stamlane.training.runs.flags_of` writes the value
    jsonargparse reads from it (YAML): a string as it is, anything else as JSON."""
    from stamlane.training.runs import flags_of

    out = []
    for arg in args:
        key, sep, text = arg.partition("=")
        if not (key.startswith("--") and sep) or key == "--config":
            out.append(arg)
            continue
        try:
            value = yaml.safe_load(text)
        except yaml.YAMLError:  # not YAML: jsonargparse reads it as the string it is
            value = text
        out += flags_of({key[2:]: text if isinstance(value, str) else value})
    return out


def _inside(path: str | Path, top: Path) -> bool:
    try:
        Path(path).resolve().relative_to(top.resolve())
    except ValueError:
        return False
    return True


class RunStore:
    """The runs and predictions of one experiment folder (see the module docstring).

    Args:
        out: the experiment's folder.
    """

    def __init__(self, out: Path) -> None:
        self.out = Path(out)

    def __repr__(self) -> str:
        return f"RunStore({str(self.out)!r})"

    # ------------------------------------------------------------------ the layout
    @staticmethod
    def run_name(row: str, seed: int | str) -> str:
        """The name of a run of ``row`` with ``seed``: its folder, and its predictions' folder."""
        return f"{row}-s{seed}"

    def folder(self, name: str) -> Path:
        """A run's folder: its record and its ``stamlane fit`` run."""
        return self.out / name

    def run_dir(self, name: str) -> Path:
        """A run's ``stamlane fit`` folder (``config.yaml``, ``metrics.csv``, ``checkpoints/``)."""
        return self.folder(name) / RUN

    def last_ckpt(self, name: str) -> Path:
        """A run's final weights (and the checkpoint a run killed midway goes on from)."""
        return self.run_dir(name) / "checkpoints" / "last.ckpt"

    @property
    def predictions(self) -> Path:
        """The folder of every run's (and oracle's) predictions."""
        return self.out / PREDICTIONS

    def pred_dir(self, name: str, split: str, source: str = "real") -> Path:
        """The predictions of a run (or an oracle) of ``split``, its history as ``source`` gives it."""
        return self.predictions / name / (split if source == "real" else f"{split}@{source}")

    def oracle_dir(self, subject: str, split: str) -> Path:
        """The predictions of an oracle of the labels (``oracle:history-4f``) of ``split``."""
        return self.pred_dir(subject.replace(":", "-"), split)

    def seeds(self, row: str) -> list[int]:
        """The seeds of ``row`` that have a finished run here."""
        found = []
        for record in sorted(self.out.glob(f"{self.run_name(row, '*')}/{DONE}")):
            seed = record.parent.name.removeprefix(f"{row}-s")
            if seed.isdigit():
                found.append(int(seed))
        return sorted(found)

    # ------------------------------------------------------------------ the records
    def finished(self, name: str, settings: dict[str, Any]) -> RunRecord | None:
        """The record of the finished run ``name`` (in today's form, `upgrade_record`), or None when it has not
        finished.

        Args:
            name: the run.
            settings: what the run must share with the experiment's others (data, steps, precision, ...); the
                record must hold the same values.

        Raises:
            ExperimentError: the record does not parse, was made with other settings, names a path outside the
                experiment's folder, or its checkpoint is missing or differs from the digest it recorded.
        """
        try:
            return self._finished(name, settings)
        except ExperimentError as err:  # every refusal names the run it refuses, not only its done file
            raise ExperimentError(f"run {name}: {err}") from None

    def _finished(self, name: str, settings: dict[str, Any]) -> RunRecord | None:
        folder = self.folder(name)
        path = folder / DONE
        if not path.is_file():
            return None
        if not _inside(folder, self.out):  # a run folder linked from elsewhere: its record is not read
            raise ExperimentError(f"{folder} leads outside {self.out} (a link?); delete it to run it again")
        try:  # only inside the run's folder: a done.json that links elsewhere is never read
            record = json.loads(read_inside(path, folder, MAX_RECORD_BYTES, "run record"))
        except GuardError as err:
            raise ExperimentError(f"{err}; delete the folder to run it again") from None
        except (RecursionError, json.JSONDecodeError) as err:
            raise ExperimentError(f"{path} is not a run record ({err}); delete the folder to run it again") from None
        if not isinstance(record, dict):
            raise ExperimentError(f"{path} is not a run record (a JSON object); delete the folder to run it again")
        record = upgrade_record(record)
        if {k: record.get(k) for k in settings} != settings:
            theirs = {k: record.get(k) for k in settings}
            raise ExperimentError(f"{folder} was made with other settings ({theirs}); use another --out")
        for key in ("run", "last_ckpt"):
            value = record.get(key)
            if value is not None and (not isinstance(value, str) or not _inside(value, self.out)):
                raise ExperimentError(
                    f"{path}: {key} {value!r} is not a path inside {self.out}; delete the folder to run it again"
                )
        try:  # every value of its field's type: a tampered record is refused, not half used
            run = RunRecord.from_json(record)
        except RecordError as err:
            raise ExperimentError(f"{path}: {err}; delete the folder to run it again") from None
        if not run.last_ckpt.is_file():
            raise ExperimentError(
                f"{path}: its checkpoint {run.last_ckpt} is missing; delete the folder to run it again"
            )
        if run.last_ckpt_sha256 is not None and file_sha256(run.last_ckpt) != run.last_ckpt_sha256:
            raise ExperimentError(
                f"{path}: its checkpoint {run.last_ckpt} changed since the run finished; delete the folder"
            )
        return run

    def mark(self, name: str, record: RunRecord) -> None:
        """Write ``record`` as the run's ``done.json`` (with its checkpoint's digest)."""
        if record.last_ckpt_sha256 is None:
            record.last_ckpt_sha256 = file_sha256(record.last_ckpt)
        write_atomic(self.folder(name) / DONE, json.dumps(record.to_json(), indent=2))
