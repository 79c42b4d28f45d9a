"""The docs cannot drift from the code: every command-line flag and every repository path they name exists.

Reads README.md, docs/*.md and evaluators/README.md. A command is ``stamlane COMMAND ...`` or ``stamlane-eval
COMMAND ...`` in a code block line or an inline code span; each of its ``--flags`` must be an option of that
command's parser (the tools' argparse parsers; for ``fit|validate|test|predict`` a key of the LightningCLI config,
matched as deep as the config goes: ``--model.postprocess.degree`` needs ``model.postprocess``). A path under
``configs/``, ``docs/``, ``src/``, ``tests/``, ``benchmarks/``, ``evaluators/`` or ``.ci/`` must exist (paths with
placeholders such as ``<id>``, ``N`` or ``*`` are patterns, not files). Every command line of a code block (and of
README's tour table) is also parsed whole by the parser that reads it (see "whole command lines" below).
"""

from __future__ import annotations

import argparse
import importlib
import re
import shlex
import sys
from collections.abc import Iterator
from functools import cache
from pathlib import Path
from typing import Any, ClassVar

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


SPAN = re.compile(r"`([^`\n]+(?:\n[^`\n]+)*)`")
"""An inline code span; a hard-wrapped paragraph may break it over lines, never over a blank line."""


def _snippets(page: Path) -> list[str]:
    """Code-block lines and inline code spans of a markdown page (commands joined across ``\\`` line ends, spans
    across the line breaks of a wrapped paragraph)."""
    text = page.read_text()
    found, block, prose = [], False, []
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i]
        if line.strip().startswith("```"):
            block = not block
            prose.append("")  # a block ends the paragraph before it
        elif block:
            while line.rstrip().endswith("\\") and i + 1 < len(lines):
                i += 1
                line = line.rstrip()[:-1] + " " + lines[i].strip()
            found.append(line)
        else:
            prose.append(line)
        i += 1
    return found + [" ".join(span.split("\n")) for span in SPAN.findall("\n".join(prose))]


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
        if program == "stamlane" and command in ("ablate", "demo"):  # what follows ``--`` goes to every run's fit
            rest, _, fit = rest.partition(" -- ")
            wrong += [f"stamlane {command} -- {f}" for f in FLAG.findall(fit) if not _lightning_flag_ok(f)]
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


# --- whole command lines -------------------------------------------------------------------------------------------
#
# Every ``stamlane ...`` / ``stamlane-eval ...`` command of a code block (and of a table whose first column is a
# command, README's tour) is parsed whole by the parser that would read it: the tools' argparse parsers, stamlane-eval's,
# and for fit / validate / test / predict `stamlane.cli.main` itself (shipped names, ``predict --stream``, the config a
# checkpoint carries) up to the end of `StamLaneCLI.parse_arguments` (``predict --ckpt_path`` without ``--config``: of
# `stamlane.training.stored_cli.parse`, the stored model opened), where nothing has been built yet. Required
# arguments, their order and every value's type count; files need not exist, except the two LightningCLI reads while
# parsing: a ``--config`` that is not here is a run's config (the one the shipped stam4-synthetic run carries), a
# ``--ckpt_path`` that is not here a run's checkpoint (that run's). A synopsis ``[--opt A|B]`` is parsed without its
# optional parts and with all of them (first and last alternative); ``...`` stands for "the same options"; the
# placeholders of a value's type (``WxH``, ``N``, ``ROW``) are given an example of that type.

SHELL_PROGRAM = re.compile(r"^(?:\S*/)?(stamlane(?:-eval)?)$")
SEPARATORS = {"&&", "||", ";", "|"}
EXAMPLE_VALUES = {"WxH": "640x360", "N": "2", "ROW": "180"}
TABLE_COMMAND = re.compile(r"^\|\s*`((?:\S*/)?stamlane(?:-eval)? [^`]+)`\s*\|")


def _shell_lines(page: Path) -> list[tuple[int, str]]:
    """``(line number, text)`` of every shell line in a code block, fenced or indented by 4 spaces after a blank line
    (``\\`` continuations joined, a ``$ `` prompt dropped, ``$VAR`` of a ``for VAR in A B; do`` of the block read
    as ``A``), and every command in the first column of a table, its ``\\|`` unescaped."""
    lines = page.read_text().splitlines()
    found, fenced, language, indented, loops, i = [], False, "", False, {}, 0
    while i < len(lines):
        line, number = lines[i], i + 1
        indented = not fenced and line.startswith("    ") and (indented or i == 0 or not lines[i - 1].strip())
        if line.strip().startswith("```"):
            fenced, language, loops = not fenced, line.strip()[3:].strip(), {}
        elif (fenced and language not in ("python", "yaml", "json", "text")) or indented:
            while line.rstrip().endswith("\\") and i + 1 < len(lines):
                i += 1
                line = line.rstrip()[:-1].rstrip() + " " + lines[i].strip()
            if loop := re.match(r"\s*for (\w+) in (\S+)", line):
                loops[loop.group(1)] = loop.group(2)
            for name, value in loops.items():
                line = re.sub(rf"\$\{{?{name}\b\}}?", value, line)
            found.append((number, line.strip().removeprefix("$ ")))
        elif not fenced and (cell := TABLE_COMMAND.match(line)):
            found.append((number, cell.group(1).replace("\\|", "|")))
        if not fenced and not indented:
            loops = {}
        i += 1
    return found


def _invocations(line: str) -> list[list[str]]:
    """The stamlane / stamlane-eval commands of a shell line (``a && b`` gives two), each as ``[program, *args]``
    with the arguments as written (quotes kept: `_variants` reads them); environment assignments before the program
    are skipped, a ``# comment`` dropped."""
    line = re.sub(r"(^|\s)#.*$", "", line)
    words = shlex.shlex(line, posix=False)
    words.whitespace_split = True
    try:
        tokens = list(words)
    except ValueError:  # not a shell line (an unbalanced quote in a diagram)
        return []
    found: list[list[str]] = []
    command: list[str] | None = None
    for token in tokens:
        if token in SEPARATORS:
            command = None
        elif command is not None:
            command.append(token)
        elif program := SHELL_PROGRAM.match(token):
            command = [program.group(1)]
            found.append(command)
    return found


def _variants(args: list[str]) -> list[list[str]]:
    """A synopsis as the concrete command lines it stands for: without its ``[optional]`` parts, and with all of
    them taking the first, then the last of each ``A|B`` alternative. A quoted word is one literal argument."""
    plain: list[str] = []
    full: list[list[str]] = [[], []]
    depth = 0
    for token in args:
        if token and token[0] in "'\"":
            plain.append(shlex.split(token)[0])
            full[0].append(plain[-1])
            full[1].append(plain[-1])
            continue
        opens, closes = token.startswith("["), token.endswith("]")
        depth += opens
        word = token.strip("[]")
        if word and word != "...":
            word = EXAMPLE_VALUES.get(word, word)
            alternatives = word.split("|")
            if depth == 0:
                plain.append(alternatives[0])
            full[0].append(alternatives[0])
            full[1].append(alternatives[-1])
        depth -= closes
    variants = [plain, *full]
    return [v for i, v in enumerate(variants) if v not in variants[:i]]


class _Parsed(Exception):
    """Raised by `_ParseOnly` once a LightningCLI command line is parsed, before anything is built."""


@cache
def _run_checkpoint() -> str:
    from stamlane.weights import shipped_path

    return str(shipped_path("stam4-synthetic"))


@cache
def _run_config(tmp: Path) -> str:
    """The config of the run that made stam4-synthetic, as a run folder holds it (``RUN/config.yaml``)."""
    from stamlane.safety.checkpoints import read_checkpoint
    from stamlane.training.lightning_cli import CONFIG_KEY

    path = tmp / "config.yaml"
    path.write_text(read_checkpoint(_run_checkpoint())[CONFIG_KEY])
    return str(path)


def _lightning_argv(args: list[str], tmp: Path) -> list[str]:
    """``args`` with a ``--config`` or ``--ckpt_path`` that is not here replaced by a run's (see above)."""
    from stamlane.safety.paths import CKPT_NAMES
    from stamlane.weights import SHIPPED

    names = {*CKPT_NAMES, *(m.name for m in SHIPPED)}
    out = list(args)
    for i, arg in enumerate(out[:-1]):
        value = out[i + 1]
        if arg in ("--config", "-c") and not (REPO / value).exists():
            out[i + 1] = _run_config(tmp)
        elif arg == "--ckpt_path" and value not in names and not (REPO / value).exists():
            out[i + 1] = _run_checkpoint()
    return out


def _parse_error(argv: list[str], tmp: Path) -> str | None:
    """Why ``argv`` (``[program, command, *args]``) does not parse; None when it does."""
    import contextlib
    import io

    from stamlane import cli

    program, command, args = argv[0], argv[1] if len(argv) > 1 else "", argv[2:]
    stderr = io.StringIO()
    try:
        with contextlib.redirect_stderr(stderr), contextlib.redirect_stdout(io.StringIO()):
            if program == "stamlane-eval":
                from stamlane_eval.cli import _build_parser

                _build_parser().parse_args(argv[1:])
            elif command == "predict" and any(a == "--stream" or a.startswith("--stream=") for a in args):
                importlib.import_module(TOOLS["stream"]).build_parser().parse_args(cli._stream_args(args))
            elif command in ("ablate", "demo") and "--" in args:  # what follows ``--`` goes to every run's fit
                cut = args.index("--")
                own = importlib.import_module(TOOLS[command]).build_parser().parse_args(args[:cut])
                base = str(getattr(own, "base", None) or REPO / "configs" / "demo.yaml")
                return _parse_error(["stamlane", "fit", "--config", base, *args[cut + 1 :]], tmp)
            elif command in TOOLS:
                importlib.import_module(TOOLS[command]).build_parser().parse_args(args)
            elif command in LIGHTNING_COMMANDS:
                status = cli.main([command, *_lightning_argv(args, tmp)])
                return stderr.getvalue().strip() or f"exit status {status} without a parse"
            else:
                return f"{program} {command}: no such command"
    except _Parsed:
        return None
    except SystemExit as stop:
        return None if not stop.code else stderr.getvalue().strip() or f"exit status {stop.code}"
    return None


@pytest.fixture(scope="module")
def parse_only(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """`StamLaneCLI` stopped at the end of its parsing, its parser built once (every `stamlane.cli.main` builds the
    same one); yields a folder for the run config."""
    from stamlane.training import lightning_cli

    class _ParseOnly(lightning_cli.StamLaneCLI):
        built: ClassVar[dict[str, Any]] = {}

        def setup_parser(self, *args: Any, **kwargs: Any) -> None:
            if not self.built:
                super().setup_parser(*args, **kwargs)
                self.built.update(vars(self))
            vars(self).update(self.built)

        def parse_arguments(self, parser: Any, args: Any) -> None:
            super().parse_arguments(parser, args)
            raise _Parsed

    from stamlane.training import stored_cli

    parse = stored_cli.parse

    def parse_only(model: Any, args: list[str], command: str = "predict") -> Any:  # a stored model's options
        parse(model, args, command)
        raise _Parsed

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(lightning_cli, "StamLaneCLI", _ParseOnly)
        patch.setattr(stored_cli, "parse", parse_only)
        patch.chdir(REPO)  # the docs' paths are relative to the repository root
        yield tmp_path_factory.mktemp("run")


def _command_lines(page: Path) -> list[tuple[int, list[str]]]:
    return [(n, argv) for n, line in _shell_lines(page) for argv in _invocations(line)]


@pytest.mark.parametrize("page", [p.relative_to(REPO).as_posix() for p in PAGES])
def test_every_command_line_of_the_docs_parses_whole(page: str, parse_only: Path) -> None:
    wrong = []
    for number, argv in _command_lines(REPO / page):
        for variant in _variants(argv):
            error = _parse_error(variant, parse_only)
            if error is not None:
                wrong.append(f"{page}:{number}: {shlex.join(variant)}\n    {error}")
    assert not wrong, "\n".join(wrong)


def test_the_docs_show_whole_command_lines() -> None:
    lines = [argv for page in PAGES for _, argv in _command_lines(page)]
    commands = {tuple(argv[:2]) for argv in lines}
    assert len(lines) > 60, len(lines)
    assert {("stamlane", c) for c in ("demo", "fit", "validate", "predict", "stream", "export", "show")} <= commands
    assert {("stamlane-eval", c) for c in ("tusimple", "culane", "video")} <= commands


def test_the_line_checker_catches_what_a_user_would_meet(parse_only: Path, tmp_path: Path) -> None:
    def error(line: str) -> str | None:
        (argv,) = _invocations(line)
        (variant,) = _variants(argv)
        return _parse_error(variant, parse_only)

    assert _invocations("A=1 .venv/bin/stamlane demo --quick && stamlane-eval tusimple p g  # x") == [
        ["stamlane", "demo", "--quick"],
        ["stamlane-eval", "tusimple", "p", "g"],
    ]
    page = tmp_path / "page.md"
    page.write_text("text\n\n    for t in 1 2; do\n      stamlane ablate --table $t \\\n        --seeds 0\n    done\n")
    assert [line for _, line in _shell_lines(page)] == [
        "for t in 1 2; do",
        "stamlane ablate --table 1 --seeds 0",
        "done",
    ]
    assert _variants(_invocations("stamlane predict --x '[a.json]' [--y 1]")[0]) == [
        ["stamlane", "predict", "--x", "[a.json]"],
        ["stamlane", "predict", "--x", "[a.json]", "--y", "1"],
    ]
    assert _variants(["x", "[--f", "a|b]", "[--n", "N]", "..."]) == [
        ["x"],
        ["x", "--f", "a", "--n", "2"],
        ["x", "--f", "b", "--n", "2"],
    ]
    assert "--root" in (error("stamlane show ROOT") or "")  # a required option missing
    assert error("stamlane show --root R --labels a.json --out O") is None
    assert error("stamlane-eval tusimple pred.json") is not None  # a positional argument missing
    assert error("stamlane-eval culane P G --size 640") is not None  # a value of the wrong type
    assert error("stamlane demo --seeds") is not None
    assert error("stamlane predict --source my.mp4") is None  # the shipped model, no checkpoint given
    assert error("stamlane predict --config RUN/config.yaml --ckpt_path CKPT --model.postprocess.degree 2") is None
    assert error("stamlane predict --ckpt_path CKPT --model.postprocess.degre 2") is not None
    assert error("stamlane fit --data.root /data") is not None  # no config
    assert error("stamlane fit --config configs/demo.yaml --trainer.max_steps ten") is not None
    assert error("stamlane ablate --table 2 -- --trainer.accelerator=gpu") is None
    assert error("stamlane ablate --table 2 -- --trainer.acelerator=gpu") is not None
    assert error("stamlane ablate --table 2 --accelerator gpu") is not None
    assert error("stamlane predict --stream drive.mp4 --ckpt CKPT") is None
    assert error("stamlane predict --stream drive.mp4 --ckpt_path CKPT") is not None
