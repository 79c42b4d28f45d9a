"""The closed registry: what a file the user did not write may build.

A checkpoint's ``hyper_parameters``, the run config it carries, a run folder's ``config.yaml`` are data. A check
by prefix (``stamlane.``) is not enough: jsonargparse resolves a name by importing its module and walking
attributes, so ``stamlane.experiments.demo.os.system`` reaches the shell. Here every name is looked up in `registry` — a table
of exact dotted names to classes: stamlane's, registered where each is defined (``@nameable``, `stamlane.types`), and the
allow-lists of torch and Lightning below — and nothing is imported or resolved from the file's text.
Every value is checked against the type the receiving parameter declares:

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

import collections.abc
import dataclasses
import datetime
import importlib
import inspect
import os
import pkgutil
import re
import tempfile
import types
import typing
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from functools import cache, partial
from pathlib import Path, PurePath
from typing import Any

from stamlane.safety.checkpoints import INSTANTIATOR, CheckpointError
from stamlane.types import nameable_objects

__all__ = [
    "CALLBACKS",
    "LOGGERS",
    "MAX_CONFIG_CHARS",
    "MAX_VALUES",
    "OPTIMIZERS",
    "SCHEDULERS",
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

_TOKEN = re.compile(r"[a-z0-9][a-z0-9_\-]*")
"""A string Lightning reads as a registered name where it also takes a class (``strategy: auto``, ``ddp``)."""
_DOTTED = re.compile(r"[^\W\d]\w*(\.[^\W\d]\w*)+")
_NOT_KEYS = ("__path__", "dict_kwargs", "class_path", "init_args")


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


class _Refused(Exception):
    """One refused value: the key (dotted, ``trainer.callbacks[0].init_args.x``) and why."""

    def __init__(self, key: str, reason: str) -> None:
        super().__init__(key, reason)
        self.key, self.reason = key, reason


@dataclasses.dataclass(frozen=True)
class _Section:
    """A config section whose keys are the parameters of ``target`` (``model:`` -> `StamLaneModule`)."""

    target: Any
    extra: Mapping[str, str] = dataclasses.field(default_factory=dict)
    """Further keys allowed, each with the one value it may have (``_instantiator``)."""


def _arms(hint: Any) -> list[Any]:
    """The alternatives of a type hint (``int | None`` -> ``[int, NoneType]``), ``Annotated`` unwrapped."""
    origin = typing.get_origin(hint)
    if origin is typing.Annotated:
        return _arms(typing.get_args(hint)[0])
    if origin in (typing.Union, types.UnionType):
        return [arm for arg in typing.get_args(hint) for arm in _arms(arg)]
    return [hint]


_SEQUENCES = (
    list,
    tuple,
    set,
    frozenset,
    collections.abc.Sequence,
    collections.abc.MutableSequence,
    collections.abc.Iterable,
    collections.abc.Collection,
    collections.abc.Set,
)
_MAPPINGS = (dict, collections.abc.Mapping, collections.abc.MutableMapping)


def _kind(arm: Any) -> str:
    """What a hint alternative takes: leaf, literal, any, seq, map, callable, dataclass, section or class."""
    if isinstance(arm, _Section):
        return "section"
    if arm in (type(None), bool, int, float, str) or arm is typing.Any or arm is object:
        return "any" if arm in (typing.Any, object) else "leaf"
    origin = typing.get_origin(arm) or arm
    if origin is typing.Literal:
        return "literal"
    if isinstance(arm, typing.TypeVar):
        return "any"
    if origin in _SEQUENCES:
        return "seq"
    if origin in _MAPPINGS:
        return "map"
    if origin is collections.abc.Callable or arm is typing.Callable:
        return "callable"
    if isinstance(arm, type) and (issubclass(arm, (PurePath, datetime.timedelta)) or arm is os.PathLike):
        return "text"  # a path or a duration, written as a string
    if isinstance(arm, type) and dataclasses.is_dataclass(arm):
        return "dataclass"
    return "class"


def _describe(hint: Any) -> str:
    text = repr(hint) if not isinstance(hint, type) else hint.__name__
    return text.replace("typing.", "").replace("collections.abc.", "")[:120]


def _describe_arms(arms: list[Any]) -> str:
    return " | ".join(_describe(arm) for arm in arms)


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def _is_plain(value: Any, depth: int = 0) -> bool:
    if depth > 50:
        return False
    if value is None or isinstance(value, (bool, int, float, str)):
        return not isinstance(value, str) or not _DOTTED.fullmatch(value)
    if isinstance(value, list):
        return all(_is_plain(v, depth + 1) for v in value)
    if isinstance(value, dict):
        return all(isinstance(k, str) and k not in _NOT_KEYS and _is_plain(v, depth + 1) for k, v in value.items())
    return False


@cache
def _hints(target: Any) -> tuple[dict[str, Any], tuple[str, ...]]:
    """``(parameter -> hint, names of the parameters)`` of a class's ``__init__`` (or a function / dataclass)."""
    if dataclasses.is_dataclass(target):
        hints = typing.get_type_hints(target)
        return hints, tuple(f.name for f in dataclasses.fields(target) if f.init)
    function = target.__init__ if isinstance(target, type) else target
    try:
        hints = typing.get_type_hints(function)
    except (NameError, TypeError, AttributeError):  # an annotation that names what is not importable: unchecked
        hints = {}
    kinds = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    names = tuple(p.name for p in inspect.signature(target).parameters.values() if p.kind in kinds)
    return hints, tuple(n for n in names if n != "self")


def _check_section(value: Any, target: Any, key: str, extra: Mapping[str, str] = {}) -> None:
    if not isinstance(value, dict):
        raise _Refused(key, f"must be a mapping of {_name(target)}'s options, got {_short(value)}")
    hints, names = _hints(target)
    for name, item in value.items():
        where = f"{key}.{name}" if key else str(name)
        if name in extra:
            if item != extra[name]:
                raise _Refused(where, f"must be {extra[name]!r}, got {_short(item)}")
            continue
        if not isinstance(name, str) or name not in names:
            raise _Refused(where, f"is not an option of {_name(target)}")
        _check(item, hints.get(name, typing.Any), where)


def _name(target: Any) -> str:
    return getattr(target, "__qualname__", None) or type(target).__name__


def _lookup(name: Any, key: str) -> Any:
    if not isinstance(name, str):
        raise _Refused(key, f"names {_short(name)}, not a class name")
    found = registry().get(name)
    if found is None:
        if "/" in name or "\\" in name or name.endswith((".yaml", ".yml", ".json")):
            raise _Refused(key, f"names the file {_short(name)}: a sub-config is never read from a stored config")
        raise _Refused(
            key,
            f"names {name!r}, not in stamlane's registry (a checkpoint or a run folder may name only stamlane's "
            f"classes, torch.optim's and Lightning's callbacks and loggers, by exact name; give your own config "
            f"with --config to use others)",
        )
    return found


def _check_class(value: dict, arms: list[Any], key: str) -> Any:
    """A ``{class_path, init_args}`` mapping: the name in the table, of a kind one of ``arms`` takes."""
    for extra in value:
        if extra not in ("class_path", "init_args"):
            raise _Refused(f"{key}.{extra}", "is not allowed beside class_path and init_args")
    target = _lookup(value.get("class_path"), f"{key}.class_path")
    if not isinstance(target, type):
        raise _Refused(f"{key}.class_path", f"names {value['class_path']!r}, a function, not a class")
    if not _fits(target, arms):
        raise _Refused(f"{key}.class_path", f"names {value['class_path']!r}, which is no {_wanted(arms)}")
    init = value.get("init_args")
    if init is not None:
        _check_section(init, target, f"{key}.init_args")
    return target


def _fits(target: Any, arms: list[Any]) -> bool:
    """Whether a table entry is of a kind one of ``arms`` takes: a subclass of a class alternative, or a class
    (or a function) returning what a ``Callable[..., R]`` alternative returns."""
    for arm in arms:
        kind = _kind(arm)
        if kind == "class" and isinstance(arm, type) and isinstance(target, type) and issubclass(target, arm):
            return True
        if kind == "callable":
            args = typing.get_args(arm)
            returns = args[-1] if args else typing.Any
            if not isinstance(returns, type):
                return True
            made = target if isinstance(target, type) else _hints(target)[0].get("return", typing.Any)
            if isinstance(made, type) and issubclass(made, returns):
                return True
    return False


def _wanted(arms: list[Any]) -> str:
    return " or ".join(_describe(arm) for arm in arms if _kind(arm) in ("class", "callable")) or "a plain value"


def _check(value: Any, hint: Any, key: str) -> None:
    """Refuse (`_Refused`) a value that is not plain and of ``hint``'s type."""
    if value is None:
        return  # never imports anything; a None where none is allowed is the receiving parser's to say
    arms = _arms(hint)
    kinds = [_kind(arm) for arm in arms]
    if "section" in kinds:
        section = arms[kinds.index("section")]
        return _check_section(value, section.target, key, section.extra)
    if isinstance(value, bool):
        ok = any(k == "any" or arm is bool or (k == "literal" and _literal(value, arm)) for arm, k in zip(arms, kinds))
    elif isinstance(value, int):
        ok = any(
            k == "any" or arm in (int, float) or (k == "literal" and _literal(value, arm))
            for arm, k in zip(arms, kinds)
        )
    elif isinstance(value, float):
        ok = any(k == "any" or arm is float for arm, k in zip(arms, kinds))
    elif isinstance(value, str):
        return _check_text(value, arms, kinds, key)
    elif isinstance(value, list):
        return _check_list(value, arms, kinds, key)
    elif isinstance(value, dict):
        return _check_mapping(value, arms, kinds, key)
    else:
        raise _Refused(key, f"is not a plain value ({type(value).__name__}: YAML tags and objects are refused)")
    if not ok:
        raise _Refused(key, f"must be {_describe(hint)}, got {_short(value)}")


def _literal(value: Any, arm: Any) -> bool:
    return any(type(value) is type(choice) and value == choice for choice in typing.get_args(arm))


def _check_text(value: str, arms: list[Any], kinds: list[str], key: str) -> None:
    plain = any(
        k in ("any", "text") or arm is str or (k == "literal" and _literal(value, arm)) for arm, k in zip(arms, kinds)
    )
    code = [arm for arm, k in zip(arms, kinds) if k in ("class", "callable", "dataclass")]
    if plain and not code:
        if "any" in kinds and _DOTTED.fullmatch(value):
            raise _Refused(key, f"is a dotted name ({value!r}) where any value goes: it could be imported")
        return
    if plain:  # a name or a class (trainer.strategy: auto): only a registered name, never a class or a file
        if not _TOKEN.fullmatch(value):
            raise _Refused(key, f"must be a lowercase name (such as 'auto') here, got {_short(value)}")
        return
    if not code:
        raise _Refused(key, f"must be {_describe_arms(arms)}, got {_short(value)}")
    if any(k == "dataclass" for k in kinds) and not any(k in ("class", "callable") for k in kinds):
        raise _Refused(key, f"must be a mapping of options, got {_short(value)} (a sub-config file is never read)")
    target = _lookup(
        value, key
    )  # a class or a function by its exact name (optimizer: stamlane.training.module.paper_sgd)
    if not _fits(target, arms):
        raise _Refused(key, f"names {value!r}, which is no {_wanted(arms)}")


def _check_list(value: list, arms: list[Any], kinds: list[str], key: str) -> None:
    for arm, k in zip(arms, kinds):
        if k == "any":
            return _check_any(value, key)
        if k != "seq":
            continue
        args = typing.get_args(arm)
        if typing.get_origin(arm) is tuple and args and args[-1] is not Ellipsis:
            if len(args) != len(value):
                raise _Refused(key, f"must hold {len(args)} values, got {_short(value)}")
            for i, (item, item_hint) in enumerate(zip(value, args)):
                _check(item, item_hint, f"{key}[{i}]")
            return None
        for i, item in enumerate(value):
            _check(item, args[0] if args else typing.Any, f"{key}[{i}]")
        return None
    raise _Refused(key, f"must be {_describe_arms(arms)}, got a list {_short(value)}")


def _check_mapping(value: dict, arms: list[Any], kinds: list[str], key: str) -> None:
    if "class_path" in value:
        if not any(k in ("class", "callable") for k in kinds):
            raise _Refused(f"{key}.class_path", f"a class where a plain value goes ({_short(value['class_path'])})")
        _check_class(value, arms, key)
        return None
    for arm, k in zip(arms, kinds):
        if k == "dataclass":
            return _check_section(value, arm, key)
        if k == "map":
            args = typing.get_args(arm)
            for name, item in value.items():
                if not isinstance(name, str) or name in _NOT_KEYS:
                    raise _Refused(f"{key}.{name}", "is not allowed as a key")
                _check(item, args[1] if len(args) == 2 else typing.Any, f"{key}.{name}")
            return None
        if k == "any":
            return _check_any(value, key)
    raise _Refused(key, f"must be {_describe_arms(arms)}, got a mapping {_short(value)}")


def _check_any(value: Any, key: str) -> None:
    if not _is_plain(value):
        raise _Refused(key, f"must be plain values (no class, no dotted name), got {_short(value)}")


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
        "trainer": _Section(Trainer),
        "model": _Section(StamLaneModule),
        "data": _Section(ClipDataModule),
        "eval": _Section(LaneEvalCallback),
        "predictions": _Section(LanePredictionWriter),
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


def _refusal(source: str | Path, what: str, err: _Refused) -> CheckpointError:
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
        raise CheckpointError(f"the config of {source} is not a mapping of options (got {_short(config)})")
    sections = _run_sections()
    try:
        for name, item in config.items():
            if name not in sections:
                raise _Refused(str(name), "is not an option of a run config")
            _check(item, sections[name], str(name))
    except _Refused as err:
        raise _refusal(source, "the config of", err) from None
    except RecursionError:
        raise CheckpointError(f"the config of {source} is nested too deeply") from None
    return config


@contextmanager
def safe_config_file(text: str, source: str | Path) -> Iterator[Path]:
    """A temporary copy of the checked run config (`check_run_config`), written from the checked data so that
    jsonargparse reads exactly what was checked (no YAML tag, anchor or alias of the original text survives)."""
    import yaml

    config = check_run_config(text, source)
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
        _check_section(hparams, StamLaneModule, "hyper_parameters", extra)
    except _Refused as err:
        raise _refusal(source, "checkpoint", err) from None
    except OldOptionError as err:
        raise CheckpointError(f"checkpoint {source}: hyper_parameters.{err}") from None
    except RecursionError:
        raise CheckpointError(f"checkpoint {source}: hyper_parameters nested too deeply") from None
    return hparams


def check_data_hparams(hparams: Any, source: str | Path) -> None:
    """Refuse a checkpoint's ``datamodule_hyper_parameters`` that are not plain ``ClipDataModule`` options (read in
    today's names: `stamlane.training.compat.group_data`)."""
    from stamlane.data.datamodule import ClipDataModule
    from stamlane.training.compat import group_data

    _check_size(hparams, f"checkpoint {source}: datamodule_hyper_parameters")
    try:
        data = group_data(hparams) if isinstance(hparams, dict) else hparams
        _check_section(data, ClipDataModule, "datamodule_hyper_parameters", {"_instantiator": INSTANTIATOR})
    except _Refused as err:
        raise _refusal(source, "checkpoint", err) from None
    except (TypeError, ValueError, AttributeError, RecursionError) as err:
        raise CheckpointError(f"checkpoint {source}: datamodule_hyper_parameters unusable: {err}") from None


def _build(value: Any, hint: Any) -> Any:
    """The object a checked value stands for: a class from the table built with its (built) init_args, or bound
    to them where a callable goes (``fusion``: ``STAM(channels, **init_args)`` later), a dataclass from its
    options, a function from the table by name; plain values as they are (a list as a tuple where one goes)."""
    arms = _arms(hint)
    kinds = [_kind(arm) for arm in arms]
    if isinstance(value, dict) and "class_path" in value:
        target = registry()[value["class_path"]]
        hints, _ = _hints(target)
        kwargs = {k: _build(v, hints.get(k, typing.Any)) for k, v in (value.get("init_args") or {}).items()}
        classes = [a for a, k in zip(arms, kinds) if k == "class" and isinstance(a, type) and issubclass(target, a)]
        return target(**kwargs) if classes or "callable" not in kinds else partial(target, **kwargs)
    if isinstance(value, str) and value in registry() and any(k in ("class", "callable") for k in kinds):
        if not any(arm is str for arm in arms):
            target = registry()[value]
            return target() if "callable" not in kinds else target
    if isinstance(value, dict) and "dataclass" in kinds:
        cls = arms[kinds.index("dataclass")]
        hints, _ = _hints(cls)
        return cls(**{k: _build(v, hints.get(k, typing.Any)) for k, v in value.items()})
    if isinstance(value, list) and any(typing.get_origin(a) is tuple for a in arms):
        return tuple(value)
    return value


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
    hints, _ = _hints(StamLaneModule)
    options = {k: v for k, v in hparams.items() if not k.startswith("_")}
    try:
        module = StamLaneModule(**{k: _build(v, hints[k]) for k, v in options.items()})
        module.load_state_dict(content["state_dict"])
    except (RuntimeError, KeyError, TypeError, ValueError, AttributeError, IndexError) as err:
        first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        raise CheckpointError(f"checkpoint {source} does not fit a stamlane network: {first[:200]}") from None
    module.hparams.update(options)  # the plain config, as Lightning's loading would record it
    return module.eval()
