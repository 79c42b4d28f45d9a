"""The closed registry: what a file the user did not write may build.

A checkpoint's ``hyper_parameters``, the run config it carries, a run folder's ``config.yaml`` are data. A check
by prefix (``stamlane.``) is not enough: jsonargparse resolves a name by importing its module and walking
attributes, so ``stamlane.experiments.demo.os.system`` reaches the shell. Here every name is looked up in `registry` — a table
of exact dotted names to classes: stamlane's, registered where each is defined (``@nameable``, `stamlane.types`), and the
allow-lists of torch and Lightning below — and nothing is imported or resolved from the file's text.
Every value is checked against the type the receiving parameter declares (`stamlane.training.typed_values`):

- a ``class_path`` (or a bare name where a class or a callable goes) must be a key of the table, of the declared
  kind (``nn.Module`` for ``model.encoder``, a ``Callback`` in ``trainer.callbacks``);
- ``init_args`` and every other value must be plain and of the declared type: numbers, strings, booleans, None,
  lists and mappings of those. A string where a class, a callable or a section goes (a callable by its dotted name,
  a sub-config file such as ``./enc.yaml``) is refused; so are unknown keys, and YAML tags (``!!python/name``,
  ``!!binary``: the text is read with ``yaml.safe_load`` and only plain values pass);
- a string where Lightning takes either a name or a class (``trainer.strategy: auto``) must be a lowercase name;
- at most `MAX_VALUES` values, YAML aliases and shared references counted each time they are used.

Anything else is a `stamlane.safety.checkpoints.CheckpointError` naming the file and the key, in one line. The checked
config is written out again (`safe_config_file`) so that jsonargparse reads exactly what was checked; a network
is built from a checkpoint's hyper_parameters by `build_module`, from the table, without jsonargparse.

This is a gate, not the way stamlane is configured: a config the user gives with ``--config`` is code, like a
script, is never checked here and may name any class (for configs, the CLI stays the registry).
"""

from __future__ import annotations

import importlib
import pkgutil
import tempfile
import types
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from functools import cache
from pathlib import Path
from typing import Any

from stamlane.safety.checkpoints import INSTANTIATOR, CheckpointError
from stamlane.training.typed_values import (
    Refused,
    Section,
    build_value,
    check_section,
    check_value,
    parameter_hints,
    short,
)
from stamlane.types import nameable_objects

__all__ = [
    "CALLBACKS",
    "LOGGERS",
    "MAX_CONFIG_CHARS",
    "MAX_VALUES",
    "OPTIMIZERS",
    "SCHEDULERS",
    "STORED_CHOICES",
    "build_module",
    "check_data_hparams",
    "check_hparams",
    "check_run_config",
    "registry",
    "safe_config_file",
]

OPTIMIZERS = (
    "SGD",
    "Adam",
    "AdamW",
    "Adagrad",
    "Adadelta",
    "Adamax",
    "ASGD",
    "NAdam",
    "RAdam",
    "RMSprop",
    "Rprop",
)
"""``torch.optim`` classes a stored config may name (``torch.optim.AdamW``)."""
SCHEDULERS = (
    "StepLR",
    "MultiStepLR",
    "ConstantLR",
    "LinearLR",
    "ExponentialLR",
    "PolynomialLR",
    "CosineAnnealingLR",
    "CosineAnnealingWarmRestarts",
    "CyclicLR",
    "OneCycleLR",
    "ReduceLROnPlateau",
)
"""``torch.optim.lr_scheduler`` classes (``LambdaLR`` and ``MultiplicativeLR`` take code, ``SequentialLR`` and
``ChainedScheduler`` built schedulers: none can come from a file)."""
CALLBACKS = (
    "ModelCheckpoint",
    "EarlyStopping",
    "LearningRateMonitor",
    "ModelSummary",
    "RichModelSummary",
    "TQDMProgressBar",
    "RichProgressBar",
    "Timer",
    "DeviceStatsMonitor",
    "StochasticWeightAveraging",
    "GradientAccumulationScheduler",
    "OnExceptionCheckpoint",
)
"""``lightning.pytorch.callbacks`` classes (not ``LambdaCallback``: it is made of code)."""
LOGGERS = ("CSVLogger", "TensorBoardLogger", "MLFlowLogger", "WandbLogger", "CometLogger")
"""``lightning.pytorch.loggers`` classes."""


_DEFINING_PACKAGES = ("stamlane.models", "stamlane.training")
"""The packages whose modules register (`stamlane.types.nameable`) what a stored run may name: every module of
them is imported by `registry`, a fixed list, never a name read from a file."""


def _import_defining_modules() -> None:
    for package_name in _DEFINING_PACKAGES:
        package = importlib.import_module(package_name)
        for found in pkgutil.iter_modules(package.__path__, f"{package_name}."):
            importlib.import_module(found.name)


@cache
def registry() -> Mapping[str, Any]:
    """Exact dotted name -> class (or function) that a checkpoint or a run folder may name.

    stamlane's own classes, registered where they are defined (`stamlane.types.nameable`), under their defining
    module's name (``stamlane.models.stam.STAM``) and the name their package exports (``stamlane.models.STAM``), as
    jsonargparse may write either; the optimisers and schedulers of `OPTIMIZERS` and `SCHEDULERS`, Lightning's
    `CALLBACKS` and `LOGGERS`; and the names of before a move (`stamlane.training.compat.RENAMED_CLASSES`:
    ``stamlane.losses.LaneLoss``), so that every earlier run and checkpoint still reads.
    """
    import torch.optim
    import torch.optim.lr_scheduler
    from lightning.pytorch import callbacks, loggers

    from stamlane.training.compat import RENAMED_CLASSES

    _import_defining_modules()
    own = dict(nameable_objects())
    registered = {id(obj) for obj in own.values()}
    for package_name in _DEFINING_PACKAGES:  # the public names: ``stamlane.models.STAM``
        package = importlib.import_module(package_name)
        for name in getattr(package, "__all__", ()):
            if id(getattr(package, name)) in registered:
                own[f"{package_name}.{name}"] = getattr(package, name)
    groups = (
        ("torch.optim", torch.optim, OPTIMIZERS),
        ("torch.optim.lr_scheduler", torch.optim.lr_scheduler, SCHEDULERS),
        ("lightning.pytorch.callbacks", callbacks, CALLBACKS),
        ("lightning.pytorch.loggers", loggers, LOGGERS),
    )
    for prefix, where, names in groups:
        found = {f"{prefix}.{name}": getattr(where, name) for name in names if hasattr(where, name)}
        own |= found | {f"{obj.__module__}.{obj.__qualname__}": obj for obj in found.values()}
    # the names of before a class moved (checkpoints and run folders written then): one table, in compat
    return types.MappingProxyType(own | {old: own[new] for old, new in RENAMED_CLASSES.items() if new in own})


@cache
def _run_sections() -> dict[str, Any]:
    """The keys of a run config (what ``stamlane fit`` writes) and what each takes."""
    from lightning.pytorch import Trainer
    from stamlane_eval.integrations.lightning import LaneEvalCallback
    from torch.optim import Optimizer
    from torch.optim.lr_scheduler import LRScheduler, ReduceLROnPlateau

    from stamlane.data.datamodule import ClipDataModule
    from stamlane.predict.prediction_writer import LanePredictionWriter
    from stamlane.training.module import StamLaneModule

    return {
        "seed_everything": bool | int | None,
        "trainer": Section(Trainer),
        "model": Section(StamLaneModule),
        "data": Section(ClipDataModule),
        "eval": Section(LaneEvalCallback),
        "predictions": Section(LanePredictionWriter),
        "source": str | None,
        "optimizer": Optimizer | None,
        "lr_scheduler": LRScheduler | ReduceLROnPlateau | None,
        "ckpt_path": str | None,
        "weights_only": bool | None,
    }


MAX_CONFIG_CHARS = 16 << 20
"""Longest run config read from a checkpoint or a run folder (as ``--config`` files; a run config is a few KiB)."""
MAX_VALUES = 100_000
"""Most values a stored config or hyper_parameters may hold, YAML aliases and pickle references counted each time
they are used (a run config holds a few hundred): a file of a few bytes that expands to billions is refused."""


def _count(value: Any, seen: dict[int, int], depth: int = 0) -> int:
    """How many values ``value`` holds once every shared reference is expanded (each shared object counted once,
    then reused: linear in the file's size)."""
    if id(value) in seen:
        return seen[id(value)]
    if depth > 100:
        return MAX_VALUES + 1
    items = value.values() if isinstance(value, dict) else value if isinstance(value, (list, tuple)) else ()
    total = 1
    for item in items:
        total += _count(item, seen, depth + 1)
        if total > MAX_VALUES:
            break
    if isinstance(value, (dict, list, tuple)):
        seen[id(value)] = total
    return total


def _check_size(value: Any, what: str) -> None:
    if _count(value, {}) > MAX_VALUES:
        raise CheckpointError(f"{what} holds more than {MAX_VALUES:,} values or is nested over 100 deep")


def _refusal(source: str | Path, what: str, err: Refused) -> CheckpointError:
    return CheckpointError(f"{what} {source}: {err.key} {err.reason}")


def check_run_config(text: str, source: str | Path) -> dict[str, Any]:
    """The run config ``text`` (from a checkpoint or a run folder's ``config.yaml``), checked against the registry.

    Returns:
        the config as plain data in today's names (`stamlane.training.compat.upgrade_config`: old flat ``data`` keys
        grouped, moved classes and renamed options under today's names), every name in it a key of `registry`.

    Raises:
        CheckpointError: not YAML, not a mapping, or a refused key (named, with why), in one line.
    """
    import yaml

    from stamlane.training.compat import OldOptionError, upgrade_config

    if not isinstance(text, str) or len(text) > MAX_CONFIG_CHARS:
        size = f"{len(text):,} characters" if isinstance(text, str) else type(text).__name__
        raise CheckpointError(
            f"the config of {source} is not a text of at most {MAX_CONFIG_CHARS:,} characters ({size})"
        )
    try:
        config = yaml.safe_load(text)
        _check_size(config, f"the config of {source}")  # before anything walks it: aliases expand there
        config = upgrade_config(config)
    except yaml.YAMLError as err:
        raise CheckpointError(f"the config of {source} is not YAML: {str(err).splitlines()[0]}") from None
    except OldOptionError as err:  # a data group that is not a mapping, an option given under two names
        raise CheckpointError(f"the config of {source}: {err}") from None
    except RecursionError:
        raise CheckpointError(f"the config of {source} is nested too deeply") from None
    if not isinstance(config, dict):
        raise CheckpointError(f"the config of {source} is not a mapping of options (got {short(config)})")
    sections = _run_sections()
    try:
        for name, item in config.items():
            if name not in sections:
                raise Refused(str(name), "is not an option of a run config")
            check_value(item, sections[name], str(name))
    except Refused as err:
        raise _refusal(source, "the config of", err) from None
    except RecursionError:
        raise CheckpointError(f"the config of {source} is nested too deeply") from None
    return config


STORED_CHOICES = ("source", "ckpt_path", "predictions.output_dir")
"""Options of a stored run config that are dropped (set to null) when it is read back: what to predict on, which
checkpoint to read and where to write are the user's to give (``--source``, ``--ckpt_path``,
``--predictions.output_dir``), never a checkpoint's: a stored ``source: /elsewhere`` would make ``predict --data.root
ROOT`` read another folder's frames and write there."""


@contextmanager
def safe_config_file(text: str, source: str | Path) -> Iterator[Path]:
    """A temporary copy of the checked run config (`check_run_config`), written from the checked data so that
    jsonargparse reads exactly what was checked (no YAML tag, anchor or alias of the original text survives)."""
    import yaml

    config = check_run_config(text, source)
    for key in STORED_CHOICES:  # a stored config never chooses what is read (the frames, a checkpoint) nor written
        section, _, option = key.rpartition(".")
        holder = config.get(section) if section else config
        if isinstance(holder, dict) and holder.get(option) is not None:
            holder[option] = None
    with tempfile.TemporaryDirectory(prefix="stamlane-config-") as folder:
        path = Path(folder) / "config.yaml"
        path.write_text(yaml.safe_dump(config, sort_keys=False))
        yield path


def check_hparams(hparams: Any, source: str | Path) -> dict[str, Any]:
    """Refuse a checkpoint's ``hyper_parameters`` that are not `StamLaneModule` options built from the registry.

    Returns:
        the hyper_parameters in today's names (`stamlane.training.compat.upgrade_hparams`).

    Raises:
        CheckpointError: naming the checkpoint and the key, in one line.
    """
    from stamlane.training.compat import OldOptionError, upgrade_hparams
    from stamlane.training.module import StamLaneModule

    extra = {"_instantiator": INSTANTIATOR, "_class_path": "stamlane.training.module.StamLaneModule"}
    _check_size(hparams, f"checkpoint {source}: hyper_parameters")
    try:
        hparams = upgrade_hparams(hparams)
        check_section(hparams, StamLaneModule, "hyper_parameters", extra)
    except Refused as err:
        raise _refusal(source, "checkpoint", err) from None
    except OldOptionError as err:
        raise CheckpointError(f"checkpoint {source}: hyper_parameters.{err}") from None
    except RecursionError:
        raise CheckpointError(f"checkpoint {source}: hyper_parameters nested too deeply") from None
    checked: dict[str, Any] = hparams  # a mapping: check_section refused anything else
    return checked


def check_data_hparams(hparams: Any, source: str | Path) -> None:
    """Refuse a checkpoint's ``datamodule_hyper_parameters`` that are not plain ``ClipDataModule`` options (read in
    today's names: `stamlane.training.compat.group_data`)."""
    from stamlane.data.datamodule import ClipDataModule
    from stamlane.training.compat import group_data

    _check_size(hparams, f"checkpoint {source}: datamodule_hyper_parameters")
    try:
        data = group_data(hparams) if isinstance(hparams, dict) else hparams
        check_section(data, ClipDataModule, "datamodule_hyper_parameters", {"_instantiator": INSTANTIATOR})
    except Refused as err:
        raise _refusal(source, "checkpoint", err) from None
    except (TypeError, ValueError, AttributeError, RecursionError) as err:
        raise CheckpointError(f"checkpoint {source}: datamodule_hyper_parameters unusable: {err}") from None


def _check_network_size(build: Any, state_dict: Any, source: str | Path) -> None:
    """Refuse hyper_parameters that build a network larger than the weights the checkpoint holds (an encoder
    ``width`` of 64 asks tens of GiB before a weight is loaded): the network is built first on torch's ``meta``
    device, which allocates nothing, and its values counted against the stored tensors'."""
    import torch

    if not isinstance(state_dict, Mapping):
        raise CheckpointError(f"checkpoint {source}: its state_dict is no mapping of tensors")
    stored = sum(t.numel() for t in state_dict.values() if isinstance(t, torch.Tensor))
    with torch.device("meta"):
        needed = sum(t.numel() for t in build().state_dict().values())
    if needed > stored:
        raise CheckpointError(
            f"checkpoint {source} does not fit a stamlane network: its hyper_parameters build {needed:,} values, its "
            f"weights hold {stored:,} (a network larger than its weights is never built)"
        )


def build_module(content: Mapping[str, Any], source: str | Path) -> Any:
    """The `StamLaneModule` of a checkpoint's content, built from the registry (never by jsonargparse), with its
    weights, on the CPU, in eval mode.

    Raises:
        CheckpointError: see `check_hparams`; also for options the classes refuse and for weights of another
            network.
    """
    from stamlane.training.module import StamLaneModule

    hparams = content.get("hyper_parameters")
    if not isinstance(hparams, dict):
        raise CheckpointError(f"checkpoint {source} records no hyper_parameters: build the network from its config")
    hparams = check_hparams(hparams, source)
    hints, _ = parameter_hints(StamLaneModule)
    options = {k: v for k, v in hparams.items() if not k.startswith("_")}
    try:
        _check_network_size(
            lambda: StamLaneModule(**{k: build_value(v, hints[k]) for k, v in options.items()}),
            content["state_dict"],
            source,
        )
        module = StamLaneModule(**{k: build_value(v, hints[k]) for k, v in options.items()})
        module.load_state_dict(content["state_dict"])
    except CheckpointError:
        raise
    except (RuntimeError, KeyError, TypeError, ValueError, AttributeError, IndexError) as err:
        first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        raise CheckpointError(f"checkpoint {source} does not fit a stamlane network: {first[:200]}") from None
    module.hparams.update(options)  # the plain config, as Lightning's loading would record it
    return module.eval()
