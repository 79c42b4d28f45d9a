"""The foundation's guards: dependency direction (STYLE.md), code style, and CI == README."""

from __future__ import annotations

import ast
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
EVAL_SRC = REPO / "evaluators" / "src" / "stamlane_eval"
SRC = REPO / "src" / "stamlane"

TORCH_STACK = ("torch", "lightning", "pytorch_lightning", "torchmetrics")


def imported_modules(path: Path) -> set[str]:
    """Absolute module names a Python file imports (relative imports resolved against its package)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    package_parts = _package_of(path)
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package_parts[: len(package_parts) - node.level + 1]
                module = ".".join([*base, node.module] if node.module else base)
            else:
                module = node.module or ""
            names.add(module)
            names.update(f"{module}.{alias.name}" for alias in node.names)
    return names


def _package_of(path: Path) -> list[str]:
    for root in (EVAL_SRC.parent, SRC.parent):
        if path.is_relative_to(root):
            return list(path.relative_to(root).parent.parts)
    return []


def violations(files: list[Path], forbidden: tuple[str, ...]) -> list[str]:
    """``file: module`` for every import of a forbidden module (or one of its submodules)."""
    found = []
    for path in files:
        shown = path.relative_to(REPO) if path.is_relative_to(REPO) else path.name
        for name in sorted(imported_modules(path)):
            if any(name == bad or name.startswith(bad + ".") for bad in forbidden):
                found.append(f"{shown}: {name}")
    return found


def _outside(files: list[Path], allowed: tuple[str, ...]) -> list[str]:
    """``file: module`` for every import of a stamlane module that is not one of ``allowed`` (or inside one)."""
    found = []
    for path in files:
        for name in sorted(imported_modules(path)):
            inside = any(name == ok or name.startswith(ok + ".") for ok in allowed)
            if name.startswith("stamlane.") and not inside:
                found.append(f"{path.relative_to(REPO)}: {name}")
    return found


def python_files(folder: Path, *, exclude: tuple[str, ...] = ()) -> list[Path]:
    return [p for p in sorted(folder.rglob("*.py")) if not any(part in exclude for part in p.parts)]


def test_evaluator_core_never_imports_the_torch_stack():
    assert violations(python_files(EVAL_SRC, exclude=("integrations",)), TORCH_STACK) == []


def test_evaluators_never_import_stamlane():
    assert violations(python_files(EVAL_SRC), ("stamlane",)) == []


FLOORS: dict[str, tuple[str, ...]] = {
    # package -> what of stamlane it may import besides itself: the floors below it (docs/architecture.md)
    "safety": ("stamlane.types",),
    "weights": (),  # the shipped models' files and their table: a leaf
    "align": ("stamlane.safety", "stamlane.types"),
    "synth": ("stamlane.align.camera", "stamlane.safety", "stamlane.types"),  # the camera, nothing else of align
    "models": ("stamlane.types",),
    # the DataModule stores its hyperparameters through the one module of private Lightning parts (a leaf)
    "data": (
        "stamlane.align",
        "stamlane.synth",
        "stamlane.safety",
        "stamlane.types",
        "stamlane.training.lightning_compat",
    ),
    "predict": ("stamlane.safety", "stamlane.types"),
    "training": (
        *("stamlane.models", "stamlane.data", "stamlane.predict", "stamlane.safety", "stamlane.types"),
        "stamlane.weights",  # a leaf: a shipped model's name as init_weights
    ),
    "stream": (
        *("stamlane.align", "stamlane.models", "stamlane.data", "stamlane.predict", "stamlane.training"),
        *("stamlane.safety", "stamlane.types", "stamlane.weights"),
    ),
    "experiments": (
        *("stamlane.synth", "stamlane.data", "stamlane.predict", "stamlane.training", "stamlane.configs"),
        *("stamlane.safety", "stamlane.types"),
    ),
}


@pytest.mark.parametrize("floor", sorted(FLOORS))
def test_each_floor_imports_only_the_floors_below_it(floor: str):
    assert _outside(python_files(SRC / floor), (f"stamlane.{floor}", *FLOORS[floor])) == []


def test_every_package_has_its_floor():
    packages = {p.parent.name for p in SRC.glob("*/__init__.py")}
    assert packages == set(FLOORS)
    top = sorted(p.name for p in SRC.glob("*.py"))
    assert top == ["__init__.py", "cli.py", "types.py"]  # the top: the command entry and the shared types


def test_pyproject_installs_every_package_and_the_configs():
    tomllib = pytest.importorskip("tomllib", reason="Python 3.11 reads TOML")
    setuptools = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
    found = ["stamlane", "stamlane.configs", *(f"stamlane.{p.parent.name}" for p in SRC.glob("*/__init__.py"))]
    assert sorted(setuptools["packages"]) == sorted(found)
    assert setuptools["package-dir"]["stamlane.configs"] == "configs"
    assert _outside([REPO / "configs" / "__init__.py"], ()) == []  # package data and one function: a leaf


def test_only_the_command_entry_knows_every_floor():
    assert violations(python_files(SRC), ("stamlane.cli",)) == []


def test_models_never_import_lightning():
    assert violations(python_files(SRC / "models"), ("lightning", "pytorch_lightning")) == []


def test_the_generator_makes_clips_without_torch():
    assert violations(python_files(SRC / "synth"), TORCH_STACK) == []


def test_lightning_compat_is_a_leaf():
    # data may import it (the one arrow up, to a module that imports nothing of stamlane's)
    assert violations([SRC / "training" / "lightning_compat.py"], ("stamlane",)) == []


def test_the_experiment_engine_knows_no_model_internals():
    # the engine drives `stamlane fit/predict` through the CLI and reads files: models and data stay behind it
    forbidden = ("stamlane.models", "stamlane.training.module", "stamlane.data.clips", "stamlane.training.losses")
    assert violations(python_files(SRC / "experiments"), forbidden) == []


def test_decoding_lanes_needs_no_lightning():
    # the package __init__ imports nothing: postprocess and the writers load without Lightning (or torch)
    code = (
        "import sys\n"
        "import stamlane.predict.postprocess, stamlane.predict.writers, stamlane.predict.overlay\n"
        "leaked = sorted(m for m in ('torch', 'lightning', 'torchmetrics') if m in sys.modules)\n"
        "assert not leaked, leaked\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr


def test_checkpoints_is_a_leaf():
    # the safe loader is training.registry (behind StamLaneModule.from_checkpoint); checkpoints.py reads files only
    assert violations([SRC / "safety" / "checkpoints.py"], ("stamlane",)) == []


def test_the_import_checker_catches_a_forbidden_import(tmp_path):
    # guard against a checker that can never fail: the imports the rules forbid are found
    bad = tmp_path / "core.py"
    bad.write_text("import numpy as np\nimport torch.nn\nfrom stamlane.models import LaneNet\n")
    assert violations([bad], TORCH_STACK) == ["core.py: torch.nn"]
    assert "core.py: stamlane.models" in violations([bad], ("stamlane",))


def test_evaluator_core_imports_with_torch_blocked():
    """Import every core module of stamlane_eval in a fresh interpreter where ``import torch`` fails."""
    modules = ["stamlane_eval"] + [
        f"stamlane_eval.{p.stem}" for p in sorted(EVAL_SRC.glob("*.py")) if p.stem not in ("__init__", "__main__")
    ]
    code = (
        "import sys\n"
        "for name in ('torch', 'lightning', 'pytorch_lightning', 'torchmetrics'):\n"
        "    sys.modules[name] = None  # any import of them now raises ImportError\n"
        f"import importlib\nfor m in {modules!r}:\n    importlib.import_module(m)\n"
        "leaked = [m for m in sys.modules if m.split('.')[0] == 'stamlane']\n"
        "assert not leaked, leaked\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr


def _readme_commands() -> list[str]:
    """The shell commands in the README's quick start, in order (the fenced block after each marker)."""
    text = (REPO / "README.md").read_text().splitlines()
    commands = []
    for i, line in enumerate(text):
        if line.strip().startswith("<!-- command"):
            block = text[i + 1 :]
            assert block[0].startswith("```"), "a quick-start marker must be followed by a fenced block"
            commands.append(block[1].strip())
    return commands


def test_readme_has_two_quick_start_commands_and_ci_runs_the_second():
    commands = _readme_commands()
    assert len(commands) == 2, commands
    ci = (REPO / ".ci" / "run").read_text().splitlines()
    assert commands[1] in ci, "'.ci/run' must run the README's test command exactly as written"
    assert "stamlane demo" in commands[0]


def _ruff() -> str:
    local = Path(sys.executable).parent / "ruff"
    found = str(local) if local.exists() else shutil.which("ruff")
    if found is None:
        pytest.skip("ruff is not installed (it comes with the `test` extra)")
    return found


def test_ruff_lint_and_format():
    ruff = _ruff()
    lint = subprocess.run([ruff, "check", str(REPO)], capture_output=True, text=True, cwd=REPO)
    assert lint.returncode == 0, lint.stdout + lint.stderr
    fmt = subprocess.run([ruff, "format", "--check", str(REPO)], capture_output=True, text=True, cwd=REPO)
    assert fmt.returncode == 0, fmt.stdout + fmt.stderr
