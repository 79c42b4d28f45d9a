"""Does a plain value fit a parameter's type hint: the value checks of the closed registry.

`check_value` walks a value read from a stored config (a checkpoint's hyper_parameters, a run folder's
``config.yaml``) against the type hint of the parameter that receives it: a ``class_path`` (or a bare dotted name
where a class or a callable goes) must name a class of the closed table (`stamlane.training.registry.registry`) of
the declared kind, and everything else must be plain (numbers, strings, booleans, None, lists and mappings of those)
and of the declared type. A refused value is a `Refused` naming its dotted key and why. `build_value` turns a
checked value into the object it stands for, from the table, without jsonargparse.
"""

from __future__ import annotations

import collections.abc
import dataclasses
import datetime
import inspect
import os
import re
import types
import typing
from collections.abc import Mapping
from functools import cache, partial
from pathlib import PurePath
from typing import Any

__all__ = [
    "Refused",
    "Section",
    "build_value",
    "check_section",
    "check_value",
    "parameter_hints",
    "refused_class",
    "short",
]


def registry() -> Mapping[str, Any]:
    """The closed table (`stamlane.training.registry.registry`), imported when first asked: that module checks
    stored configs with this one."""
    from stamlane.training.registry import registry as table

    return table()


_TOKEN = re.compile(r"[a-z0-9][a-z0-9_\-]*")
"""A string Lightning reads as a registered name where it also takes a class (``strategy: auto``, ``ddp``)."""


_DOTTED = re.compile(r"[^\W\d]\w*(\.[^\W\d]\w*)+")


_NOT_KEYS = ("__path__", "dict_kwargs", "class_path", "init_args")


class Refused(Exception):
    """One refused value: the key (dotted, ``trainer.callbacks[0].init_args.x``) and why."""

    def __init__(self, key: str, reason: str) -> None:
        super().__init__(key, reason)
        self.key, self.reason = key, reason


@dataclasses.dataclass(frozen=True)
class Section:
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
    if isinstance(arm, Section):
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


_REFUSED_CLASS = (  # jsonargparse's words for a class that is not of the kind its key takes, most telling first
    (re.compile(r"Import path (?P<name>\S+) does not correspond to a subclass of (?P<base>\w+)"), "is no {} subclass"),
    (re.compile(r"Expected '(?P<name>[^']+)' to be a subclass of <class '(?P<base>\w+)'>"), "is no {} subclass"),
    (re.compile(r"Expected '(?P<name>[^']+)' to be a function that returns <class '(?P<base>\w+)'>"), "is no {} class"),
    (  # a class that is no optimizer, given with init_args of its own (``os.system``'s ``command``)
        re.compile(r"Callable\[.*?\.(?P<base>\w+)\] expects .*Got value: Namespace\(class_path='(?P<name>[^']+)'"),
        "is no {} class",
    ),
)
_PARSER_KEY = re.compile(r'Parser key "([^"]+)":')


def refused_class(message: str) -> str | None:
    """One short line for jsonargparse's message on a class its key does not take (``trainer.callbacks``,
    ``trainer.logger``, ``model.optimizer`` naming ``os.system`` or a Logger where a Callback goes): 400-odd
    characters of union subtypes and type hints become ``Parser key "trainer.logger": os.system is no Logger
    subclass``. None for any other message (it is said as jsonargparse says it)."""
    key = _PARSER_KEY.match(message)
    if key is None:
        return None
    for pattern, words in _REFUSED_CLASS:
        found = pattern.search(message)
        if found is not None:
            name, base = found["name"], found["base"]
            return f'Parser key "{key[1]}": {short(name)[1:-1]} {words.format(base)}'
    return None


def short(value: Any) -> str:
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
def parameter_hints(target: Any) -> tuple[dict[str, Any], tuple[str, ...]]:
    """``(parameter -> hint, names of the parameters)`` of a class's ``__init__`` (or a function / dataclass)."""
    if dataclasses.is_dataclass(target):
        hints = typing.get_type_hints(target)
        return hints, tuple(f.name for f in dataclasses.fields(target) if f.init)
    is_class = isinstance(target, type)  # (not narrowed: mypy refuses __init__ on a narrowed type)
    function = target.__init__ if is_class else target
    try:
        hints = typing.get_type_hints(function)
    except (NameError, TypeError, AttributeError):  # an annotation that names what is not importable: unchecked
        hints = {}
    kinds = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    names = tuple(p.name for p in inspect.signature(target).parameters.values() if p.kind in kinds)
    return hints, tuple(n for n in names if n != "self")


def check_section(value: Any, target: Any, key: str, extra: Mapping[str, str] = {}) -> None:
    if not isinstance(value, dict):
        raise Refused(key, f"must be a mapping of {_name(target)}'s options, got {short(value)}")
    hints, names = parameter_hints(target)
    for name, item in value.items():
        where = f"{key}.{name}" if key else str(name)
        if name in extra:
            if item != extra[name]:
                raise Refused(where, f"must be {extra[name]!r}, got {short(item)}")
            continue
        if not isinstance(name, str) or name not in names:
            raise Refused(where, f"is not an option of {_name(target)}")
        check_value(item, hints.get(name, typing.Any), where)


def _name(target: Any) -> str:
    return getattr(target, "__qualname__", None) or type(target).__name__


def _lookup(name: Any, key: str) -> Any:
    if not isinstance(name, str):
        raise Refused(key, f"names {short(name)}, not a class name")
    found = registry().get(name)
    if found is None:
        if "/" in name or "\\" in name or name.endswith((".yaml", ".yml", ".json")):
            raise Refused(key, f"names the file {short(name)}: a sub-config is never read from a stored config")
        # short: the key and the name say it; docs/safety.md says what the registry holds and that --config may
        # name any class
        raise Refused(
            key, f"names {short(name)}, not in the registry (a stored config may name only stamlane's classes)"
        )
    return found


def _check_class(value: dict[str, Any], arms: list[Any], key: str) -> Any:
    """A ``{class_path, init_args}`` mapping: the name in the table, of a kind one of ``arms`` takes."""
    for extra in value:
        if extra not in ("class_path", "init_args"):
            raise Refused(f"{key}.{extra}", "is not allowed beside class_path and init_args")
    target = _lookup(value.get("class_path"), f"{key}.class_path")
    if not isinstance(target, type):
        raise Refused(f"{key}.class_path", f"names {value['class_path']!r}, a function, not a class")
    if not _fits(target, arms):
        raise Refused(f"{key}.class_path", f"names {value['class_path']!r}, which is no {_wanted(arms)}")
    init = value.get("init_args")
    if init is not None:
        check_section(init, target, f"{key}.init_args")
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
            made = target if isinstance(target, type) else parameter_hints(target)[0].get("return", typing.Any)
            if isinstance(made, type) and issubclass(made, returns):
                return True
    return False


def _wanted(arms: list[Any]) -> str:
    return " or ".join(_describe(arm) for arm in arms if _kind(arm) in ("class", "callable")) or "a plain value"


def check_value(value: Any, hint: Any, key: str) -> None:
    """Refuse (`Refused`) a value that is not plain and of ``hint``'s type."""
    if value is None:
        return  # never imports anything; a None where none is allowed is the receiving parser's to say
    arms = _arms(hint)
    kinds = [_kind(arm) for arm in arms]
    if "section" in kinds:
        section = arms[kinds.index("section")]
        return check_section(value, section.target, key, section.extra)
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
        raise Refused(key, f"is not a plain value ({type(value).__name__}: YAML tags and objects are refused)")
    if not ok:
        raise Refused(key, f"must be {_describe(hint)}, got {short(value)}")


def _literal(value: Any, arm: Any) -> bool:
    return any(type(value) is type(choice) and value == choice for choice in typing.get_args(arm))


def _check_text(value: str, arms: list[Any], kinds: list[str], key: str) -> None:
    plain = any(
        k in ("any", "text") or arm is str or (k == "literal" and _literal(value, arm)) for arm, k in zip(arms, kinds)
    )
    code = [arm for arm, k in zip(arms, kinds) if k in ("class", "callable", "dataclass")]
    if plain and not code:
        if "any" in kinds and _DOTTED.fullmatch(value):
            raise Refused(key, f"is a dotted name ({value!r}) where any value goes: it could be imported")
        return
    if plain:  # a name or a class (trainer.strategy: auto): only a registered name, never a class or a file
        if not _TOKEN.fullmatch(value):
            raise Refused(key, f"must be a lowercase name (such as 'auto') here, got {short(value)}")
        return
    if not code:
        raise Refused(key, f"must be {_describe_arms(arms)}, got {short(value)}")
    if any(k == "dataclass" for k in kinds) and not any(k in ("class", "callable") for k in kinds):
        raise Refused(key, f"must be a mapping of options, got {short(value)} (a sub-config file is never read)")
    target = _lookup(
        value, key
    )  # a class or a function by its exact name (optimizer: stamlane.training.module.paper_sgd)
    if not _fits(target, arms):
        raise Refused(key, f"names {value!r}, which is no {_wanted(arms)}")


def _check_list(value: list[Any], arms: list[Any], kinds: list[str], key: str) -> None:
    for arm, k in zip(arms, kinds):
        if k == "any":
            return _check_any(value, key)
        if k != "seq":
            continue
        args = typing.get_args(arm)
        if typing.get_origin(arm) is tuple and args and args[-1] is not Ellipsis:
            if len(args) != len(value):
                raise Refused(key, f"must hold {len(args)} values, got {short(value)}")
            for i, (item, item_hint) in enumerate(zip(value, args)):
                check_value(item, item_hint, f"{key}[{i}]")
            return None
        for i, item in enumerate(value):
            check_value(item, args[0] if args else typing.Any, f"{key}[{i}]")
        return None
    raise Refused(key, f"must be {_describe_arms(arms)}, got a list {short(value)}")


def _check_mapping(value: dict[str, Any], arms: list[Any], kinds: list[str], key: str) -> None:
    if "class_path" in value:
        if not any(k in ("class", "callable") for k in kinds):
            raise Refused(f"{key}.class_path", f"a class where a plain value goes ({short(value['class_path'])})")
        _check_class(value, arms, key)
        return None
    for arm, k in zip(arms, kinds):
        if k == "dataclass":
            return check_section(value, arm, key)
        if k == "map":
            args = typing.get_args(arm)
            for name, item in value.items():
                if not isinstance(name, str) or name in _NOT_KEYS:
                    raise Refused(f"{key}.{name}", "is not allowed as a key")
                check_value(item, args[1] if len(args) == 2 else typing.Any, f"{key}.{name}")
            return None
        if k == "any":
            return _check_any(value, key)
    raise Refused(key, f"must be {_describe_arms(arms)}, got a mapping {short(value)}")


def _check_any(value: Any, key: str) -> None:
    if not _is_plain(value):
        raise Refused(key, f"must be plain values (no class, no dotted name), got {short(value)}")


def build_value(value: Any, hint: Any) -> Any:
    """The object a checked value stands for: a class from the table built with its (built) init_args, or bound
    to them where a callable goes (``fusion``: ``STAM(channels, **init_args)`` later), a dataclass from its
    options, a function from the table by name; plain values as they are (a list as a tuple where one goes)."""
    arms = _arms(hint)
    kinds = [_kind(arm) for arm in arms]
    if isinstance(value, dict) and "class_path" in value:
        target = registry()[value["class_path"]]
        hints, _ = parameter_hints(target)
        kwargs = {k: build_value(v, hints.get(k, typing.Any)) for k, v in (value.get("init_args") or {}).items()}
        classes = [a for a, k in zip(arms, kinds) if k == "class" and isinstance(a, type) and issubclass(target, a)]
        return target(**kwargs) if classes or "callable" not in kinds else partial(target, **kwargs)
    if isinstance(value, str) and value in registry() and any(k in ("class", "callable") for k in kinds):
        if not any(arm is str for arm in arms):
            target = registry()[value]
            return target() if "callable" not in kinds else target
    if isinstance(value, dict) and "dataclass" in kinds:
        cls = arms[kinds.index("dataclass")]
        hints, _ = parameter_hints(cls)
        return cls(**{k: build_value(v, hints.get(k, typing.Any)) for k, v in value.items()})
    if isinstance(value, list) and any(typing.get_origin(a) is tuple for a in arms):
        return tuple(value)
    return value
