"""The ``stamlane`` command.

``stamlane fit|validate|test|predict --config ...`` is LightningCLI (the only place that knows both the
LightningModule and the DataModule); the other subcommands are plain tools with their own ``main``.
"""

from __future__ import annotations

import importlib
import sys

__all__ = ["main"]

# subcommand -> module whose ``main(argv) -> int`` runs it; imported only when asked for, so
# ``stamlane synth`` does not pay for importing Lightning.
TOOLS: dict[str, str] = {
    "align": "stamlane.align.cli",  # precompute homographies for a dataset
    "synth": "stamlane.data.synth_cli",  # write a synthetic clip set in the TuSimple layout
    "show": "stamlane.data.show_cli",  # picture grid of clips with targets, for checking a conversion
    "demo": "stamlane.demo",  # README command 1: synthetic data, train, evaluate, pictures
}

LIGHTNING_COMMANDS = ("fit", "validate", "test", "predict")


def _usage() -> str:
    names = ", ".join([*LIGHTNING_COMMANDS, *TOOLS])
    return f"usage: stamlane {{{names}}} ..."


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help"):
        print(_usage())
        return 0 if argv else 2
    command, rest = argv[0], argv[1:]
    if command in TOOLS:
        return int(importlib.import_module(TOOLS[command]).main(rest) or 0)
    print(f"stamlane: unknown command {command!r}; {_usage()}", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main())
