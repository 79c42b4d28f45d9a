"""The docs cannot drift from the code: every command-line flag and every repository path they name exists.

Reads README.md, docs/*.md and evaluators/README.md. A command is ``stamlane COMMAND ...`` or ``stamlane-eval
COMMAND ...`` in a code block line or an inline code span; each of its ``--flags`` must be an option of that
command's parser (the tools' argparse parsers; for ``fit|validate|test|predict`` a key of the LightningCLI config,
matched as deep as the config goes: ``--model.postprocess.degree`` needs ``model.postprocess``). A path under
``configs/``, ``docs/``, ``src/``, ``tests/``, ``benchmarks/``, ``evaluators/`` or ``.ci/`` must exist (paths with
placeholders such as ``<id>``, ``N`` or ``*`` are patterns, not files).
"""

from __future__ import annotations

import argparse
import importlib
import re
import sys
from functools import cache
from pathlib import Path

import pytest

from stamlane.cli import LIGHTNING_COMMANDS, TOOLS

REPO = Path(__file__).resolve().parents[1]
PAGES = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md")), REPO / "evaluators" / "README.md"]
COMMAND = re.compile(r"(?<![\w/.-])(stamlane(?:-eval)?) ([a-z][a-z-]*)((?: +[^\s`|]+)*)")
FLAG = re.compile(r"(?<![\w-])(--[a-z][\w.-]*[\w])")
PATH = re.compile(r"(?<![\w/.-])((?:configs|docs|src|tests|benchmarks|evaluators|\.ci)/[\w./*<>{}-]*[\w/*>}])")
PLACEHOLDER = re.compile(r"[<>*{}]|/N\b|/ID\b|/DIR\b")
LIGHTNING_TOP = {
    "--config",
    "--print_config",
    "--ckpt_path",
    "--seed_everything",
    "--source",
    "--verbose",
    "--weights_only",
    "--help",
}


def _snippets(page: Path) -> list[str]:
    """Code-block lines and inline code spans of a markdown page (commands joined across ``\\`` line ends)."""
    text = page.read_text()
    found, block = [], False
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i]
        if line.strip().startswith("```"):
            block = not block
        elif block:
            while line.rstrip().endswith("\\") and i + 1 < len(lines):
                i += 1
                line = line.rstrip()[:-1] + " " + lines[i].strip()
            found.append(line)
        else:
            found += re.findall(r"`([^`]+)`", line)
        i += 1
    return found


def _commands() -> list[tuple[str, str, str, str]]:
    """``(page, program, command, rest of the line)`` of every command the docs show."""
    found = []
    for page in PAGES:
        for snippet in _snippets(page):
            for program, command, rest in COMMAND.findall(snippet):
                found.append((page.relative_to(REPO).as_posix(), program, command, rest))
    return found


def _options(parser: argparse.ArgumentParser) -> set[str]:
    return {opt for action in parser._actions for opt in action.option_strings}


@cache
def _tool_options(program: str, command: str) -> set[str] | None:
    """The options of a tool's parser (None: not a command of ``program``)."""
    if program == "stamlane-eval":
        from stamlane_eval import cli

        sub = next(a for a in cli._build_parser()._actions if isinstance(a, argparse._SubParsersAction))
        return _options(sub.choices[command]) | {"--help"} if command in sub.choices else None
    if command not in TOOLS:
        return None
    return _options(importlib.import_module(TOOLS[command]).build_parser()) | {"--help"}


def test_every_tool_builds_its_parser_by_one_name() -> None:
    for command, module in TOOLS.items():
        parser = importlib.import_module(module).build_parser()
        assert isinstance(parser, argparse.ArgumentParser), command
        assert parser.prog.endswith(command), (command, parser.prog)


@cache
def _config_keys() -> frozenset[str]:
    """Every key of the ``stamlane fit`` config (dotted), from the demo config's resolved form."""
    from stamlane.training.lightning_cli import StamLaneCLI

    argv, sys.argv = sys.argv, sys.argv[:1]
    try:
        cli = StamLaneCLI(args=["--config", str(REPO / "configs" / "demo.yaml")], run=False)
    finally:
        sys.argv = argv
    keys: set[str] = set()

    def walk(node: object, prefix: str) -> None:
        items = vars(node).items() if hasattr(node, "__dict__") else node.items() if isinstance(node, dict) else ()
        for key, value in items:
            name = f"{prefix}.{key}" if prefix else str(key)
            keys.add(name.replace(".init_args", ""))
            walk(value, name)

    walk(cli.config, "")
    return frozenset(keys)


def _lightning_flag_ok(flag: str) -> bool:
    if flag in LIGHTNING_TOP:
        return True
    key = flag[2:].split("+=")[0]
    parts = key.split(".")
    keys = _config_keys()
    # matched as deep as the config goes (a class given on the command line may add its own arguments)
    depth = max((n for n in range(1, len(parts) + 1) if ".".join(parts[:n]) in keys), default=0)
    return depth >= min(2, len(parts))


def test_the_docs_show_commands() -> None:
    commands = _commands()
    assert len(commands) > 40 and {c[2] for c in commands} >= {"demo", "fit", "predict", "tusimple", "culane"}


@pytest.mark.parametrize("page", [p.relative_to(REPO).as_posix() for p in PAGES])
def test_every_flag_the_docs_name_is_an_option_of_its_command(page: str) -> None:
    wrong = []
    for where, program, command, rest in _commands():
        if where != page:
            continue
        flags = FLAG.findall(rest)
        if program == "stamlane" and command == "predict" and "--stream" in flags:  # dispatched to `stamlane stream`
            command, flags = "stream", [f for f in flags if f != "--stream"]
        if program == "stamlane" and command in LIGHTNING_COMMANDS:
            wrong += [f"stamlane {command} {f}" for f in flags if not _lightning_flag_ok(f)]
            continue
        options = _tool_options(program, command)
        if options is None:
            wrong.append(f"{program} {command}: no such command")
            continue
        wrong += [f"{program} {command} {f}" for f in flags if f.split("=")[0] not in options]
    assert not wrong, f"{page}: {sorted(set(wrong))}"


@pytest.mark.parametrize("page", [p.relative_to(REPO).as_posix() for p in PAGES])
def test_every_repository_path_the_docs_name_exists(page: str) -> None:
    text = (REPO / page).read_text()
    missing = sorted(
        {
            p
            for p in PATH.findall(text)
            if not PLACEHOLDER.search(p) and not (REPO / p).exists() and not (REPO / p.rstrip(".")).exists()
        }
    )
    assert not missing, f"{page} names paths that do not exist: {missing}"


def test_the_checker_catches_a_wrong_flag_and_a_missing_path(tmp_path: Path) -> None:
    assert not _lightning_flag_ok("--data.nope") and _lightning_flag_ok("--data.root")
    assert _lightning_flag_ok("--model.postprocess.degree") and not _lightning_flag_ok("--model.nope.degree")
    assert "--ckpt" in _tool_options("stamlane", "stream") and "--ckpt_path" not in _tool_options("stamlane", "stream")
    assert PATH.findall("see configs/nope.yaml and `src/stamlane/experiments/demo.py`") == [
        "configs/nope.yaml",
        "src/stamlane/experiments/demo.py",
    ]
