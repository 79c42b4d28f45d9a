"""One ablation run: train a row's config with one seed, test it on the test and challenging splits.

The run is ``stamlane fit`` (``StamLaneCLI``) called in this process, so Lightning is imported once, not
once per run. Its arguments are, in this order (later ones win): the base config and the shared layers,
the user's extra arguments (so they act as part of the base and a row's own settings still hold), the
row's config, and the runner's own settings (seed, run folder, budget, data root), which no row sets.
The fit's trainer then scores the final weights with ``trainer.test`` on the test split and, when the
label file exists under the data root, on the challenging split (a second DataModule with the same
settings and ``test_labels=[challenging]``).

A run killed midway resumes from its ``last.ckpt`` when the base config saves one (``save_last``).
"""

from __future__ import annotations

import inspect
import json
import platform
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import torch

__all__ = ["RunSpec", "cli_args", "run"]

_LOG_NAME, _LOG_VERSION = "logs", "run"


@dataclass(frozen=True)
class RunSpec:
    """What one run needs.

    Attributes:
        configs: base config and shared layers, in composition order.
        row: the row's config (applied after ``configs`` and ``extra``).
        seed: ``seed_everything``.
        out_dir: the run's folder (logs, checkpoints, ``config.yaml``).
        max_steps: training steps (None: the base's).
        minutes: wall-clock limit of the training (``trainer.max_time``; the poly LR still spans
            ``max_steps``).
        data_root: ``data.root`` (None: the base's; the synthetic set when that is null).
        accelerator: ``trainer.accelerator`` (None: the base's).
        challenging: label file of the challenging split, relative to the data root (None: skip it).
        extra: further ``stamlane fit`` arguments, applied after ``configs`` and before ``row``
            (``--data.test_labels=[test_label.json]``).
        keep_checkpoints: keep the run's checkpoints after it finished (default: delete them).
    """

    configs: tuple[Path, ...]
    row: Path
    seed: int
    out_dir: Path
    max_steps: int | None = None
    minutes: float | None = None
    data_root: str | None = None
    accelerator: str | None = None
    challenging: str | None = "challenging.json"
    extra: tuple[str, ...] = field(default_factory=tuple)
    keep_checkpoints: bool = False


def _max_time(minutes: float) -> str:
    """``trainer.max_time`` as Lightning's ``DD:HH:MM:SS``."""
    seconds = max(1, round(minutes * 60))
    days, rest = divmod(seconds, 86400)
    hours, rest = divmod(rest, 3600)
    mins, secs = divmod(rest, 60)
    return f"{days:02d}:{hours:02d}:{mins:02d}:{secs:02d}"


def cli_args(spec: RunSpec) -> list[str]:
    """The ``stamlane fit`` arguments (after the subcommand) of a run."""
    args = [f"--config={c}" for c in spec.configs]
    args += [*spec.extra, f"--config={spec.row}"]
    args += [
        f"--seed_everything={spec.seed}",
        f"--trainer.default_root_dir={spec.out_dir}",
        "--trainer.logger=lightning.pytorch.loggers.CSVLogger",
        f"--trainer.logger.save_dir={spec.out_dir}",
        f"--trainer.logger.name={_LOG_NAME}",
        f"--trainer.logger.version={_LOG_VERSION}",
    ]
    if spec.max_steps is not None:
        args.append(f"--trainer.max_steps={spec.max_steps}")
    if spec.minutes is not None:
        args.append(f"--trainer.max_time={_max_time(spec.minutes)}")
    if spec.data_root is not None:
        args.append(f"--data.root={spec.data_root}")
    if spec.accelerator is not None:
        args.append(f"--trainer.accelerator={spec.accelerator}")
    return args


def _strip(metrics: dict[str, Any], prefix: str = "test/") -> dict[str, float]:
    return {k[len(prefix) :]: float(v) for k, v in metrics.items() if k.startswith(prefix)}


def _with_test_labels(data: Any, labels: list[str]) -> Any:
    """A copy of a DataModule (same init arguments, as it saved them) whose test split reads ``labels``."""
    params = inspect.signature(type(data)).parameters
    kwargs = {k: v for k, v in data.hparams.items() if k in params}
    return type(data)(**{**kwargs, "test_labels": labels})


def _hardware(trainer: Any) -> str:
    accel = type(trainer.accelerator).__name__.replace("Accelerator", "").lower()
    if accel == "cuda" and torch.cuda.is_available():
        return f"cuda: {torch.cuda.get_device_name(0)}"
    return f"{accel}: {_cpu_name()}, {torch.get_num_threads()} threads"


def _cpu_name() -> str:
    """The CPU model (``/proc/cpuinfo`` on Linux), else the platform's machine name."""
    cpuinfo = Path("/proc/cpuinfo")
    if cpuinfo.is_file():
        for line in cpuinfo.read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    return platform.processor() or platform.machine()


def run(spec: RunSpec) -> dict[str, Any]:
    """Train and test one row with one seed.

    Args:
        spec: the run.

    Returns:
        the result dict (``metrics`` per split, settings, timings) to store as ``result.json``.
    """
    from stamlane.cli import build_cli  # Lightning is imported only when a run starts

    spec.out_dir.mkdir(parents=True, exist_ok=True)
    args = cli_args(spec)
    last = spec.out_dir / _LOG_NAME / _LOG_VERSION / "checkpoints" / "last.ckpt"
    resumed = last.is_file()
    fit_args = ["fit", *args, *([f"--ckpt_path={last}"] if resumed else [])]
    start = time.perf_counter()
    cli = build_cli(fit_args)  # `stamlane fit`: trains, writes its config.yaml beside the logs
    train_s = time.perf_counter() - start
    trainer, model, data, config = cli.trainer, cli.model, cli.datamodule, cli.config["fit"]
    steps = int(trainer.global_step)

    metrics: dict[str, dict[str, float] | None] = {}
    start = time.perf_counter()
    metrics["test"] = _strip(trainer.test(model, datamodule=data, verbose=False)[0])
    challenging = None
    if spec.challenging is not None and (Path(data.root) / spec.challenging).is_file():
        challenging = _with_test_labels(data, [spec.challenging])
        metrics["challenging"] = _strip(trainer.test(model, datamodule=challenging, verbose=False)[0])
    test_s = time.perf_counter() - start

    if not spec.keep_checkpoints and last.parent.is_dir():
        shutil.rmtree(last.parent)
    return {
        "seed": spec.seed,
        "metrics": metrics,
        "steps": steps,
        "resumed": resumed,
        "train_seconds": round(train_s, 2),
        "test_seconds": round(test_s, 2),
        "num_frames": int(config.data.num_frames),
        "fusion": str(config.model.fusion.class_path),
        "fusion_args": json.loads(json.dumps(dict(config.model.fusion.get("init_args") or {}), default=str)),
        "align": str(config.data.align),
        "data_root": str(data.root),
        "challenging_labels": spec.challenging if challenging is not None else None,
        "hardware": _hardware(trainer),
        "torch": torch.__version__,
        "args": fit_args,
        "finished": time.strftime("%Y-%m-%d %H:%M:%S"),
    }
