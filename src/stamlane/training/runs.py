"""Runs from Python: the one typed way to make a run, open a stored one and predict with it.

- `RunSpec`: what a run is made of, as data: its configs (in order) and the options over them (``{"trainer.max_steps":
  300, "data.clip.image_size": [64, 128]}``, keyed by the dotted names of ``stamlane fit --help``);
- `fit` trains a spec with a seed (from scratch, or from the weights ``init``) into a run folder and returns its
  `RunRecord`; a run killed midway goes on from its ``last.ckpt``;
- `open_run` opens a checkpoint or a run folder: the one gate (its config checked against the closed registry and read
  in today's names, `stamlane.training.registry` / `stamlane.training.compat`; the checkpoint read within the budget,
  `stamlane.safety.checkpoints`), and returns a `Run`;
- `predict` (`Run.predict`) writes a run's predictions of a split with its history as a `Probe` fills it. An opened run
  opens its checkpoint once, at its first prediction, as a `stamlane.training.stored.StoredModel` (not read again
  when `open_run` read it), and each split and probe is a plain ``Trainer.predict`` of it
  (`stamlane.training.stored_predict`).

Training is LightningCLI's (`stamlane.training.lightning_cli.StamLaneCLI`), given its arguments as a list: the options
of a spec become the flags ``stamlane fit`` would read (`flags_of`), so that a run made here is the run ``stamlane fit``
makes of the same config and options, bit for bit (tests/training/test_runs.py).
"""

from __future__ import annotations

import json
import time
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from stamlane.data.probes import PROBES, REAL, Probe
from stamlane.training.run_record import RecordError, RunRecord

if TYPE_CHECKING:
    from stamlane.data.options import ClipOptions
    from stamlane.training.stored import StoredModel

__all__ = [
    "PROBES",
    "REAL",
    "Probe",
    "RecordError",
    "Run",
    "RunError",
    "RunRecord",
    "RunSpec",
    "fit",
    "flags_of",
    "open_run",
    "overrides_of",
    "predict",
    "run_cli",
]


EXACT_ALIGN = "true"
"""``data.clip.align`` of `Probe.exact`: the generator's exact homographies (`stamlane.data.alignment.ALIGN_MODES`)."""


class RunError(ValueError):
    """A run that cannot be made or opened (a config refused, a checkpoint unreadable, options that do not parse)."""


# ---------------------------------------------------------------------- options as data, flags at the call
def flags_of(overrides: Mapping[str, Any]) -> list[str]:
    """The command-line flags of options keyed by their dotted names, in order: ``{"trainer.max_steps": 2}`` ->
    ``["--trainer.max_steps=2"]``; ``config`` (a path or a list of them) -> ``--config PATH`` each; a key ending in
    ``+`` appends (``{"trainer.callbacks+": "stamlane.training.history_use_monitor.HistoryUseMonitor"}``). A string
    or a path is passed as it is (as typed on a command line); any other value as JSON, which jsonargparse reads as
    the YAML it is (``["blank", "glare"]``, ``true``, ``null``)."""
    flags: list[str] = []
    for key, value in overrides.items():
        if key == "config":
            for config in value if isinstance(value, (list, tuple)) else [value]:
                flags += ["--config", str(config)]
        else:
            text = str(value) if isinstance(value, (str, Path)) else json.dumps(value, default=str)
            flags.append(f"--{key}={text}")
    return flags


def overrides_of(args: Sequence[str]) -> dict[str, Any]:
    """Options typed on a command line (``--key=value``, ``--key value``, ``--config PATH``) as data, values kept as
    the strings typed (`flags_of` gives them back). An option given twice holds its last value, as on a command line
    (it moves to the end, where the command line would read it last).

    Raises:
        RunError: an argument that is not an option, an option without a value, or an appending option
            (``--key+=``) given twice (a mapping keeps one value a key: the first would be lost).
    """
    out: dict[str, Any] = {}
    i = 0
    while i < len(args):
        arg = args[i]
        if not arg.startswith("--") or arg == "--":
            raise RunError(f"{arg!r} is not an option (--key=value)")
        if "=" in arg:
            key, value = arg[2:].split("=", 1)
            i += 1
        elif i + 1 < len(args):
            key, value = arg[2:], args[i + 1]
            i += 2
        else:
            raise RunError(f"option {arg} has no value")
        if key in ("config", "c"):
            out["config"] = [*out.get("config", []), value]
        elif key in out and key.endswith("+"):
            raise RunError(f"option --{key} given twice; put both values in one list")
        else:
            out.pop(key, None)
            out[key] = value
    return out


@dataclass(frozen=True)
class RunSpec:
    """What a run is made of (see the module docstring).

    Attributes:
        configs: its ``stamlane fit`` configs, in order (a later one overrides an earlier one).
        overrides: options over the configs, keyed by dotted names (`flags_of`), applied after every config.
        base: options applied after the FIRST config only, as part of the base that the later configs override (an
            experiment's settings for every row, under each row's own configs).
    """

    configs: tuple[Path, ...]
    overrides: Mapping[str, Any] = field(default_factory=dict)
    base: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.configs:
            raise RunError("a run needs at least one config")

    def with_overrides(self, overrides: Mapping[str, Any]) -> RunSpec:
        """This spec with ``overrides`` after its own (a key given again moves to the end, with the new value)."""
        mine = {k: v for k, v in self.overrides.items() if k not in overrides}
        return replace(self, overrides={**mine, **overrides})

    def args(self) -> list[str]:
        """The ``stamlane fit`` arguments of the spec (after the subcommand)."""
        args = ["--config", str(self.configs[0]), *flags_of(self.base)]
        for config in self.configs[1:]:
            args += ["--config", str(config)]
        return [*args, *flags_of(self.overrides)]


def run_cli(args: list[str], cli: type | None = None, **kwargs: Any) -> Any:
    """LightningCLI (`StamLaneCLI`, or its subclass ``cli``) run on ``args`` (the subcommand first), never on
    ``sys.argv``: the one call of LightningCLI, from Python and from ``stamlane fit|validate|test|predict``.
    ``kwargs`` go to `StamLaneCLI` (``report`` False unless given: the caller reports)."""
    from stamlane.training.lightning_cli import StamLaneCLI

    with warnings.catch_warnings():  # args are given on purpose: sys.argv is this process's, not the run's
        warnings.filterwarnings("ignore", message=r".*LightningCLI's args parameter is intended", category=UserWarning)
        return (cli or StamLaneCLI)(args=args, **{"report": False, **kwargs})


# ---------------------------------------------------------------------- making a run
def fit(spec: RunSpec, seed: int = 0, init: Path | None = None, *, run_dir: Path) -> RunRecord:
    """Train ``spec`` with ``seed`` into ``run_dir`` (``config.yaml``, ``metrics.csv``, ``checkpoints/last.ckpt``),
    from scratch or from the weights ``init``; a ``last.ckpt`` already there (a run killed midway) is resumed.

    Returns:
        the run's record (its settings empty: the caller's to add).

    Raises:
        RunError: options that do not parse, a checkpoint to start or resume from that is refused (one line).
    """
    from stamlane.safety.boundary import one_line
    from stamlane.safety.checkpoints import CheckpointError

    run_dir = Path(run_dir)
    last = run_dir / "checkpoints" / "last.ckpt"
    where = {  # the logger's folder is the run folder: save_dir/name/version
        "trainer.default_root_dir": run_dir.parent,
        "trainer.logger.save_dir": run_dir.parent.parent,
        "trainer.logger.name": run_dir.parent.name,
        "trainer.logger.version": run_dir.name,
    }
    options = {**({"model.init_weights": init} if init else {}), "seed_everything": seed}
    spec = spec.with_overrides(options).with_overrides(where)
    start = time.perf_counter()
    try:
        cli = run_cli(["fit", *([f"--ckpt_path={last}"] if last.is_file() else []), *spec.args()])
    except CheckpointError as err:  # a tampered checkpoint to resume or start from: one line
        raise RunError(f"{run_dir}: {one_line(err)}") from None
    folder = Path(cli.trainer.logger.log_dir)
    return RunRecord(
        run=folder,
        last_ckpt=folder / "checkpoints" / "last.ckpt",
        frames=cli.datamodule.clip.num_frames,
        seed=seed,
        train_minutes=round((time.perf_counter() - start) / 60, 2),
        hardware=_hardware(),
    )


# ---------------------------------------------------------------------- opening a run
@dataclass
class Run:
    """A stored run, opened by `open_run`: its checkpoint and its checked config; its model is built and its
    checkpoint loaded once, at its first `predict`, and reused by every later one (`close` lets them go).

    Attributes:
        ckpt: the checkpoint.
        config: the run's config as plain data, checked against the registry, in today's names.
        source: where the config was read (the checkpoint, or the run folder's ``config.yaml``).
        start_dir: the folder ``stamlane fit`` was started in (recorded in its checkpoints), if known.
    """

    ckpt: Path
    config: dict[str, Any]
    source: Path
    text: str = field(repr=False)
    start_dir: str | None = None
    _stored: StoredModel | None = field(default=None, repr=False)
    _content: dict[str, Any] | None = field(default=None, repr=False)

    def __enter__(self) -> Run:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Let the model go."""
        self._stored = self._content = None

    def data(self) -> dict[str, Any]:
        data = self.config.get("data")
        return data if isinstance(data, dict) else {}

    @property
    def frames(self) -> int:
        """The clip length (T) of the run."""
        return self.clip.num_frames

    @property
    def aligns(self) -> bool:
        """Whether the run pre-aligns its history on the fly (``data.clip.align: fly``, the default)."""
        return self.clip.align == "fly"

    @property
    def clip(self) -> ClipOptions:
        """How the run read its clips (`stamlane.data.options.ClipOptions`, in today's names; an older run's flat
        data options too).

        Raises:
            RunError: data options that are no `ClipOptions`.
        """
        from stamlane.training.compat import clip_options

        try:
            return clip_options(self.data())
        except ValueError as err:
            raise RunError(f"{self.source}: {err}") from None

    def data_root(self) -> Path | None:
        """The data root to give the run (`stamlane.training.stored.data_root` of its recorded root).

        Raises:
            DataError: a relative root found nowhere, naming the flag to give.
        """
        from stamlane.training.stored import data_root

        recorded = self.data().get("root")
        return data_root(recorded if isinstance(recorded, str) else None, self.start_dir, self.ckpt)

    def predict(
        self, split: str, probe: Probe | str, out: Path, *, root: Path | None = None, max_overlays: int = 0
    ) -> Path:
        """Predict the label file ``<split>.json`` of the data root with the run's weights, its history as ``probe``
        fills it, into ``out`` (``predictions.json``, ``per_image.jsonl``, overlays); returns ``out``.

        The run's checkpoint is opened once, at the first prediction (`stamlane.training.stored.StoredModel`), and
        every prediction is a plain ``Trainer.predict`` of it (`stamlane.training.stored_predict.predict_stored`).

        Args:
            split: the label file's stem.
            probe: the history probe (`Probe` or its name).
            out: the predictions' folder.
            root: the data root (None: the run's own).
            max_overlays: overlay pictures to write.

        Raises:
            RunError: the run's config or checkpoint refused, or options the data module refuses (one line).
        """
        from stamlane.predict.prediction_writer import LanePredictionWriter
        from stamlane.safety.boundary import one_line
        from stamlane.training.lightning_cli import checkpoint_name
        from stamlane.training.stored import StoredModel
        from stamlane.training.stored_predict import (
            check_prediction_outputs,
            name_predictions,
            predict_stored,
            prediction_trainer_options,
        )
        from stamlane.training.typed_values import parameter_hints

        probe = Probe.of(probe)
        try:
            if self._stored is None:  # the first prediction builds the model; the checkpoint is read once in all
                content, self._content = self._content, None
                beside = (self.source, self.text) if self.source != self.ckpt else None  # its config.yaml: read
                self._stored = (
                    StoredModel.of_content(self.ckpt, content, beside) if content else StoredModel.open(self.ckpt)
                )
            model = self._stored
            data = model.datamodule(
                **({"root": str(root)} if root is not None else {}),
                predict_labels=[f"{split}.json"],
                history_source=probe.history,
                **({"clip": {"align": EXACT_ALIGN}} if probe.exact else {}),
            )
            _, names = parameter_hints(LanePredictionWriter)
            stored = {k: v for k, v in model.section("predictions").items() if k in names}
            options = {"output_dir": str(out), "max_overlays": max_overlays, "verbose": False}
            writer = LanePredictionWriter(**{**stored, **options})
            name_predictions(writer, data, None, checkpoint_name(str(self.ckpt), []))
            check_prediction_outputs(writer, [data.root], [self.ckpt])
            trainer = prediction_trainer_options(model.section("trainer")) | {"enable_progress_bar": False}
            predict_stored(model, data, writer, seed=(model.config or {}).get("seed_everything", 0), **trainer)
        except ValueError as err:  # a tampered run folder or checkpoint: one line
            raise RunError(f"{self.source}: {one_line(err)}") from None
        return Path(out)


def open_run(where: str | Path) -> Run:
    """Open a stored run: a checkpoint (its config travels inside it, else the run's ``config.yaml`` beside
    ``checkpoints/``) or a run folder (its ``config.yaml`` and ``checkpoints/last.ckpt``).

    Raises:
        RunError: no checkpoint, a checkpoint over the budget or unreadable, a config that is no file of the run
            folder or that the registry refuses (one line).
    """
    from stamlane.safety.budget import MAX_RECORD_BYTES
    from stamlane.safety.checkpoints import CheckpointError, read_checkpoint
    from stamlane.safety.guard import GuardError, read_inside
    from stamlane.safety.paths import PathError, check_config_paths
    from stamlane.training.lightning_cli import CONFIG_KEY, START_DIR_KEY
    from stamlane.training.registry import check_run_config
    from stamlane.training.stored import config_beside

    path = Path(where)
    start: Any = None
    text: Any = None
    content: Any = None
    try:
        if path.is_dir():  # a run folder: its config.yaml, read only inside it
            ckpt, source = path / "checkpoints" / "last.ckpt", path / "config.yaml"
            if not ckpt.is_file():
                raise RunError(f"{path} holds no checkpoints/last.ckpt (not a finished run folder)")
            text = read_inside(source, path, MAX_RECORD_BYTES, "run config")
        else:
            content = read_checkpoint(path)
            ckpt, source, text, start = path, path, content.get(CONFIG_KEY), content.get(START_DIR_KEY)
            if not isinstance(text, str):  # a checkpoint of before configs travelled in them: the run's config.yaml
                beside = config_beside(path)
                if beside is None:
                    raise RunError(f"checkpoint {path} carries no config and none is beside it: give --config")
                source, text = beside
        config = check_run_config(text, source)
        check_config_paths(config)
    except (CheckpointError, GuardError, PathError) as err:
        raise RunError(str(err)) from None
    kept = content if not path.is_dir() else None  # read already: its first prediction does not read it again
    return Run(ckpt, config, source, text, start if isinstance(start, str) else None, _content=kept)


def predict(run: Run, split: str, probe: Probe | str, out: Path, **options: Any) -> Path:
    """`Run.predict`: ``split`` predicted with ``run``'s weights, its history as ``probe`` fills it, into ``out``."""
    return run.predict(split, probe, out, **options)


def _hardware() -> str:
    """The CPU (or GPU), threads and torch version a run trained on."""
    import torch

    from stamlane.training.hardware import cpu_name

    if torch.cuda.is_available():
        return f"cuda: {torch.cuda.get_device_name(0)}, torch {torch.__version__}"
    return f"cpu: {cpu_name()}, {torch.get_num_threads()} threads, torch {torch.__version__}"
