"""The ``stamlane`` command.

``stamlane fit|validate|test|predict --config ...`` is LightningCLI (`StamLaneCLI`, the only place that
knows both the LightningModule and the DataModule); the other subcommands are plain tools with their own
``main``.

What `StamLaneCLI` adds to plain LightningCLI:

- ``data.clip.num_frames``, ``data.clip.image_size`` and ``data.clip.crop_top`` are linked into ``model.num_frames``
  / ``model.image_size`` / ``model.crop_top`` (written once, in the data section's clip options,
  `stamlane.data.options`); a config with the flat data keys of before (``data.num_frames``) is read grouped;
- ``LaneEvalCallback`` (stamlane-eval) is always on, configured under ``eval:`` (TuSimple metrics for
  frames with ``h_samples``, the CULane IoU F1 for all): validation logs ``val/tusimple_f1``,
  ``val/culane_f1@0.5``, ...;
- ``LanePredictionWriter`` is always on, configured under ``predictions:`` (``stamlane predict`` writes
  TuSimple json / CULane text and overlay pictures);
- ``--source PATH`` (predict only): a folder of frames or a video file instead of the data split;
- ``seed_everything`` defaults to 0 (runs repeat); ``--trainer.deterministic true`` for deterministic
  kernels; checkpoints hold only tensors and plain values and are loaded with ``weights_only=True``
  (torch's default; ``--weights_only false`` only for a trusted, foreign checkpoint).
"""

from __future__ import annotations

import importlib
import sys

from stamlane.safety.boundary import one_line, peer_failure, share_failure
from stamlane.safety.paths import (
    CKPT_NAMES,
    PathError,
    check_arguments,
    check_command_files,
    inspect_path,
)

__all__ = ["LIGHTNING_COMMANDS", "TOOLS", "main"]

# subcommand -> module whose ``main(argv) -> int`` runs it; imported only when asked for, so
# ``stamlane synth`` does not pay for importing Lightning.
TOOLS: dict[str, str] = {
    "align": "stamlane.align.cli",
    "synth": "stamlane.synth.cli",
    "show": "stamlane.data.show_cli",
    "demo": "stamlane.experiments.demo",
    "ablate": "stamlane.experiments.ablate",
    "report": "stamlane.experiments.report_cli",
    "stream": "stamlane.stream.cli",
    "export": "stamlane.stream.export_cli",
    "adapt": "stamlane.training.adapt_cli",
}

LIGHTNING_COMMANDS = ("fit", "validate", "test", "predict")

SUMMARIES: dict[str, str] = {
    "fit": "train a model from a config (LightningCLI; --help lists every option)",
    "validate": "score a checkpoint on the validation split",
    "test": "score a checkpoint on the test split",
    "predict": "write lanes (TuSimple json / CULane text) and overlays for a split, a folder or a video",
    "demo": "synthetic clips -> train 3 models -> scores with confidence intervals, pictures",
    "synth": "write a synthetic clip set in the TuSimple layout",
    "align": "estimate (and cache, or write out) the pre-alignment of a dataset",
    "show": "picture grid of clips with their targets, to check a dataset",
    "stream": "per-frame streaming inference on a video or a folder of frames",
    "export": "a checkpoint to ONNX, with the parity against PyTorch printed",
    "adapt": "a model adapted to your camera from your own unlabelled video (docs/adapt.md)",
    "ablate": "the paper's ablation tables over seeds",
    "report": "the tables of experiment summaries (demo, ablate), the paper's tables",
}
"""One line per command for ``stamlane --help``."""


def _version() -> str:
    import stamlane

    return str(stamlane.__version__)


def _usage() -> str:
    names = ", ".join([*LIGHTNING_COMMANDS, *TOOLS])
    return f"usage: stamlane {{{names}}} ... | --help | --version"


def _help() -> str:
    width = max(map(len, SUMMARIES))
    lines = [
        _usage(),
        "",
        "Lane detection with pre-aligned spatial-temporal attention (Chen & Xiang, Sensors 2022).",
        "",
    ]
    lines += [f"  {name:<{width}}  {text}" for name, text in SUMMARIES.items()]
    from stamlane.weights import DEFAULT, SHIPPED

    lines += [
        "",
        f"Shipped weights (--ckpt_path NAME, stream --ckpt NAME; predict --source runs {DEFAULT}; docs/models.md):",
    ]
    named = max(len(m.name) for m in SHIPPED)
    lines += [f"  {m.name:<{named}}  {m.summary}" for m in SHIPPED]
    lines += [
        "",
        "stamlane COMMAND --help gives the command's options; evaluators: stamlane-eval --help.",
        "Documentation: README.md and docs/ in the source repository.",
    ]
    return "\n".join(lines)


def _stream_args(rest: list[str]) -> list[str]:
    """``predict --stream VIDEO [options]`` -> the arguments of ``stamlane stream VIDEO [options]``."""
    for i, arg in enumerate(rest):
        if arg.startswith("--stream="):
            return [arg.split("=", 1)[1], *rest[:i], *rest[i + 1 :]]
        if arg == "--stream":
            return [*rest[i + 1 : i + 2], *rest[:i], *rest[i + 2 :]]
    return rest


def _given_config(rest: list[str]) -> bool:
    return any(a in ("--config", "-c") or a.startswith(("--config=", "-c=")) for a in rest)


def _stored_command(command: str, rest: list[str]) -> bool:
    """Whether ``rest`` asks ``predict``, ``validate`` or ``test`` of a stored model: a ``--ckpt_path`` (a checkpoint,
    a run folder, a shipped name) without ``--config``, and no help asked for (`stamlane.training.stored_cli`)."""
    ckpt = _option(rest, "--ckpt_path")
    stored = ckpt not in (None, *CKPT_NAMES) and not _given_config(rest) and not _asks_help(rest)
    return command in ("predict", "validate", "test") and stored


def _option(rest: list[str], name: str) -> str | None:
    """The value of ``name`` (``--name VALUE`` or ``--name=VALUE``) in ``rest``, the last one given; None if absent."""
    value = None
    for i, arg in enumerate(rest):
        if arg.startswith(f"{name}="):
            value = arg.split("=", 1)[1]
        elif arg == name and i + 1 < len(rest):
            value = rest[i + 1]
    return value


_NO_RUN = ("-h", "--help", "--print_config", "--print-config")


def _missing_input(command: str, rest: list[str]) -> str | None:
    """What is missing from a LightningCLI command line, said before torch and Lightning are imported (so
    without waiting for those imports): a ``--ckpt_path`` or ``--config`` file that does not exist, or
    neither of them where one is needed. None when nothing is missing; the message says what to give."""
    if _asks_help(rest):
        return None
    ckpt = _option(rest, "--ckpt_path")
    configs = [a.split("=", 1)[1] for a in rest if a.startswith(("--config=", "-c="))]
    configs += [rest[i + 1] for i, a in enumerate(rest[:-1]) if a in ("--config", "-c")]
    if ckpt is not None and ckpt not in CKPT_NAMES and not inspect_path(ckpt).exists:
        ckpt = ckpt or "''"  # an empty value typed: shown as one
        if command == "fit":
            return (
                f"checkpoint {ckpt} does not exist: give the path of the run to resume's checkpoint "
                "(RUN/checkpoints/last.ckpt, or the best one `stamlane fit` printed) or --ckpt_path last"
            )
        return (
            f"checkpoint {ckpt} does not exist: give the path of a trained run's checkpoint (RUN/checkpoints/last.ckpt, "
            f"or the best one `stamlane fit` printed) or a shipped model's name ({_shipped_names()})"
        )
    for config in configs:
        if not inspect_path(config).exists:
            return f"config {config} does not exist (see stamlane {command} --help)"
    if configs or ckpt is not None or any(a.startswith("--model.") for a in rest):
        return None
    if command == "fit":
        return "give --config CONFIG (configs/demo.yaml trains the demo's model on CPU; see stamlane fit --help)"
    return (
        "give --ckpt_path CKPT (a trained run's checkpoint; its config travels inside it) or --config CONFIG "
        f"(see stamlane {command} --help)"
    )


def _shipped_names() -> str:
    from stamlane.weights import SHIPPED

    return ", ".join(m.name for m in SHIPPED)


def _with_shipped_weights(command: str, rest: list[str]) -> list[str]:
    """``rest`` with a shipped model's name or a run folder given to ``--ckpt_path`` replaced by its checkpoint file
    (`stamlane.training.stored.checkpoint_of`: a folder's ``checkpoints/last.ckpt``; a shipped name's file, where no
    file or folder of that name is here, as the user typed the name; ``model.init_weights`` is resolved where it is
    read, `StamLaneModule.setup`, wherever it was written), and ``stamlane predict
    --source X`` given no checkpoint, no config and no model option run with the default shipped model (said in one
    line on stderr): its file, whatever lies here under its name, since nobody typed that name.

    Raises:
        CheckpointError: a folder given to ``--ckpt_path`` that is no finished run (no ``checkpoints/last.ckpt``).
    """
    from stamlane.training.stored import checkpoint_of
    from stamlane.weights import DEFAULT, SHIPPED, shipped_path

    def checkpoint(value: str) -> str:
        return str(checkpoint_of(value)) if value else value  # an empty value is no folder ("." is): left as typed

    out = []
    for i, arg in enumerate(rest):
        if arg.startswith("--ckpt_path="):
            arg = "--ckpt_path=" + checkpoint(arg.split("=", 1)[1])
        elif i and rest[i - 1] == "--ckpt_path":
            arg = checkpoint(arg)
        out.append(arg)
    given = _option(out, "--ckpt_path") is not None or any(
        a in ("--config", "-c") or a.startswith(("--config=", "-c=", "--model.")) for a in out
    )
    if command == "predict" and _option(out, "--source") is not None and not given and not _asks_help(out):
        print(
            f"stamlane predict: no --ckpt_path given: running the shipped {DEFAULT} ("
            + next(m.summary for m in SHIPPED if m.name == DEFAULT)
            + "; what it can and cannot do: docs/models.md)",
            file=sys.stderr,
        )
        out = ["--ckpt_path", str(shipped_path(DEFAULT)), *out]  # a name nobody typed: never a file of that name here
    return out


def _asks_help(rest: list[str]) -> bool:
    return any(arg.split("=", 1)[0] in _NO_RUN for arg in rest)


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv:
        print(_usage(), file=sys.stderr)
        return 2
    if argv[0] in ("-h", "--help"):
        print(_help())
        return 0
    if argv[0] in ("-V", "--version"):
        print(f"stamlane {_version()}")
        return 0
    command, rest = argv[0], argv[1:]
    if command == "predict" and any(arg == "--stream" or arg.startswith("--stream=") for arg in rest):
        command, rest = "stream", _stream_args(rest)
    try:  # the door: an argument that can be no usable path (a name too long, a loop of links) is one line
        check_arguments(rest)
    except PathError as err:
        print(f"stamlane {command}: {one_line(err)}", file=sys.stderr)
        return 2
    if command in TOOLS:
        return int(importlib.import_module(TOOLS[command]).main(rest) or 0)
    if command in LIGHTNING_COMMANDS:
        try:  # every path through the gate first (a run folder as its checkpoint, a shipped name as its file): a
            # name too long, a FIFO or a device is one line, never opened
            shipped = _with_shipped_weights(command, rest)
            check_command_files(shipped, missing_ok=True)
        except (PathError, ValueError) as err:  # ValueError: checkpoint_of's CheckpointError (its module imports torch)
            print(f"stamlane {command}: {one_line(err)}", file=sys.stderr)
            return 2
        rest = shipped
        missing = _missing_input(command, rest)
        if missing is not None:  # said in a fraction of a second, before torch and Lightning are imported
            print(f"stamlane {command}: {missing}", file=sys.stderr)
            return 2
        from jsonargparse import ArgumentError
        from lightning.fabric.utilities.exceptions import MisconfigurationException

        from stamlane.data.labels import DataError
        from stamlane.training.quiet import quiet_libraries

        if "--verbose" in rest:  # everything the libraries say (not an option of LightningCLI's: taken out)
            rest = [a for a in rest if a != "--verbose"]
        else:
            quiet_libraries()

        try:
            if _stored_command(command, rest):  # the checkpoint opened once, a plain Trainer.predict|validate|test
                from stamlane.training.stored_cli import main_stored

                main_stored(rest, command)
                return 0
            from stamlane.training.runs import run_cli  # once the libraries are quieted

            # the arguments as given (never sys.argv's); a bad option or config raises instead of printing
            # jsonargparse's hundred-line usage
            run_cli([command, *rest], report=True, parser_kwargs={"exit_on_error": False})
        except ArgumentError as err:
            print(f"stamlane {command}: {one_line(err)} (see stamlane {command} --help)", file=sys.stderr)
            return 2
        except (DataError, OSError, ValueError, MisconfigurationException) as err:  # bad input (or a place that
            # cannot be written, by Lightning's own writers too): status 2, the same line from every process
            share_failure(one_line(err))
            print(f"stamlane {command}: {one_line(err)}", file=sys.stderr)
            return 2
        except RuntimeError as err:  # a collective broken by another process leaving on a bad input: its line
            line = peer_failure(err)
            if line is None:
                raise
            print(f"stamlane {command}: {line}", file=sys.stderr)
            return 2
        return 0
    print(f"stamlane: unknown command {command!r}; {_usage()}", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main())
