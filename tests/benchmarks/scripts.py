"""A benchmark script (``benchmarks/<name>.py``, not a package) loaded as a module, for the tests of its functions.

A script imports ``_harness`` and its siblings by their names, as ``python benchmarks/<name>.py`` finds them (the
script's folder on ``sys.path``). Here a finder placed last on ``sys.meta_path`` finds them in ``benchmarks/``: only a
top-level name that nothing else on the path answers and that is a script there, so no installed module is shadowed.
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import importlib.util
import sys
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from types import ModuleType

REPO = Path(__file__).resolve().parents[2]
BENCHMARKS = REPO / "benchmarks"


class _Siblings(importlib.abc.MetaPathFinder):
    """Finds ``_harness`` and the other scripts of ``benchmarks/`` by their module names."""

    def find_spec(
        self, fullname: str, path: Sequence[str] | None = None, target: ModuleType | None = None
    ) -> importlib.machinery.ModuleSpec | None:
        script = BENCHMARKS / f"{fullname}.py"
        if path is not None or "." in fullname or not script.is_file():
            return None
        return importlib.util.spec_from_file_location(fullname, script)


if not any(isinstance(finder, _Siblings) for finder in sys.meta_path):
    sys.meta_path.append(_Siblings())


def load_script(name: str) -> ModuleType:
    """``benchmarks/<name>.py`` as the module ``bench_<name>``, registered in ``sys.modules`` (its dataclasses,
    pickles and forked processes find it by name) for the rest of the session."""
    spec = importlib.util.spec_from_file_location(f"bench_{name}", BENCHMARKS / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        sys.modules.pop(spec.name, None)
        raise
    return module


@contextmanager
def benchmark_module(name: str) -> Iterator[ModuleType]:
    """`load_script` while the block runs, its registration removed after (another test file's load of the same
    script keeps its own)."""
    key = f"bench_{name}"
    before = sys.modules.get(key)
    try:
        yield load_script(name)
    finally:
        if before is None:
            sys.modules.pop(key, None)
        else:
            sys.modules[key] = before
