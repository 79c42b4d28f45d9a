"""What ``stamlane demo`` and ``stamlane ablate`` set up before an experiment runs: its data, its precision and its
output folder, the same way for both.

- `check_data` / `prepare_data`: ``--data`` a folder (never another set's labels written over), or the default
  synthetic set generated where it is missing; ``--quick``'s tiny synthetic set;
- `add_bf16_argument` / `bf16_of`: ``--bf16 auto|true|false`` (``auto``: where the CPU runs bfloat16 natively);
- `claimed_out`: ``--out`` checked (a folder, never among the inputs), created and locked while the experiment
  writes it.
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from stamlane.experiments.store import ExperimentError

__all__ = [
    "FIT_ARGUMENTS_HELP",
    "QUICK_DATA",
    "add_bf16_argument",
    "bf16_of",
    "check_data",
    "claimed_out",
    "fit_arguments",
    "prepare_data",
    "split_name",
]

QUICK_DATA = "quick_data"
"""Where ``--quick`` generates its tiny set without ``--data``: in ``--out``."""


FIT_ARGUMENTS_HELP = "arguments after -- go to every run's stamlane fit (-- --trainer.accelerator=gpu)"


def fit_arguments(argv: list[str]) -> tuple[list[str], list[str]]:
    """``argv`` cut at its first ``--``: the command's own arguments, and those after it, which every run's
    ``stamlane fit`` gets after the row's base config (``-- --trainer.accelerator=gpu``)."""
    if "--" not in argv:
        return argv, []
    cut = argv.index("--")
    return argv[:cut], argv[cut + 1 :]


def split_name(value: str) -> str:
    """``--splits``: the stem of a label file in the data root (``reveal`` for ``<root>/reveal.json``); a path, a
    parent reference or an odd name is refused (argparse: one line, exit status 2), so nothing is read outside the
    root."""
    import re

    if not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,99}", value) or ".." in value:
        raise argparse.ArgumentTypeError(
            f"{value[:60]!r} is not a split name (the stem of a label file in the data root)"
        )
    return value


def check_data(root: Path | None, *, quick: bool = False, must_exist: bool = False) -> None:
    """Refuse, before anything is made, a ``--data`` that is not a folder (or is missing, with ``must_exist``),
    and one that holds another set's labels without the synthetic ``dataset.json`` where ``--quick`` would generate
    its tiny set over them."""
    if root is None:
        return
    if root.is_symlink() and not root.exists():  # --quick would make its set there: through the link, then fail
        raise ExperimentError(f"--data {root} is a link to nothing")
    if (root.exists() or must_exist) and not root.is_dir():
        raise ExperimentError(f"--data {root} is not a folder")
    labels = [name for name in ("train.json", "val.json", "test.json") if os.path.lexists(root / name)]
    if quick and labels and not (root / "dataset.json").is_file():  # a set of someone else's: never written over
        raise ExperimentError(
            f"--data {root} holds {labels[0]} but no dataset.json: not a synthetic set, --quick would write over "
            "it; give an empty or synthetic folder"
        )


def prepare_data(root: Path | None, out: Path, *, quick: bool = False, generate: bool = True) -> Path:
    """The data root of an experiment, ready to train on.

    Args:
        root: ``--data``: None for the default synthetic set (`stamlane.synth.layout.DEFAULT_SYNTHETIC_ROOT`,
            generated with a progress bar when missing).
        out: ``--out`` (``--quick`` without ``--data`` generates its set there).
        quick: a tiny synthetic set, two clips per factor (an interval per factor), generated where ``root`` has
            no ``dataset.json``.
        generate: generate the default synthetic set at a ``root`` that holds no ``train.json`` (``stamlane
            demo``); False: ``root`` is used as it is (``stamlane ablate``: a TuSimple-layout set).

    Returns:
        the data root.
    """
    from stamlane.data.datamodule import ClipDataModule
    from stamlane.synth import FACTORS, SynthConfig, generate_dataset
    from stamlane.synth.config import REVEAL, REVEAL_TRAFFIC
    from stamlane.synth.layout import DEFAULT_SYNTHETIC_ROOT, SplitCounts

    check_data(root, quick=quick, must_exist=not generate)
    if quick:
        root = root or out / QUICK_DATA
        if not (root / "dataset.json").is_file():
            generate_dataset(
                root,
                SplitCounts(
                    train=4,
                    val=2,
                    test=2,
                    challenging=2 * len(FACTORS),
                    reveal=2 * len(REVEAL),
                    reveal_traffic=2 * len(REVEAL_TRAFFIC),
                    train_motion=2,
                ),
                config=SynthConfig(width=256, height=144, num_frames=4),
                progress=False,
            )
        return root
    if root is None:
        ClipDataModule(root=None).prepare_data()  # generates it when missing, with a progress bar
        return Path(DEFAULT_SYNTHETIC_ROOT)
    if generate and not (root / "train.json").is_file():  # the default set's settings, generated at the given place
        ClipDataModule(root=None).generate_synthetic(root)
    return root


def add_bf16_argument(parser: argparse.ArgumentParser) -> None:
    """``--bf16 auto|true|false``."""
    parser.add_argument(
        "--bf16",
        choices=("auto", "true", "false"),
        default="auto",
        help="bfloat16 autocast (auto: where the CPU runs it natively; false: float32, as on an AVX2-only CPU)",
    )


def bf16_of(choice: str, quick: bool = False) -> bool:
    """``--bf16`` as a bool: ``auto`` is whether this CPU runs bfloat16 natively (`stamlane.training.hardware`);
    float32 for ``--quick`` unless asked."""
    from stamlane.training.hardware import resolve_bf16

    if quick and choice == "auto":
        return False
    return resolve_bf16({"true": True, "false": False}.get(choice, choice))


@contextmanager
def claimed_out(
    out: Path, files: Iterable[Path], reads: Iterable[Path | None] = (), protected: Iterable[Path | None] = ()
) -> Iterator[None]:
    """``out`` checked, created and held while the block writes it: a folder (not a file), none of its ``files``
    (the command's outputs at its top) nor their temporary names among the ``reads``, and nothing written inside a
    ``protected`` folder (the data); a second command writing the same ``out`` at once is refused.

    Raises:
        GuardError: as `stamlane.safety.guard.check_outputs` and `stamlane.safety.guard.exclusive` say.
    """
    from stamlane.safety.guard import check_outputs, exclusive, make_folder, temporary_name

    files = list(files)
    check_outputs([*files, *map(temporary_name, files)], list(reads), folders=[out], protected=list(protected))
    make_folder(out, "--out")
    with exclusive(out):
        yield
