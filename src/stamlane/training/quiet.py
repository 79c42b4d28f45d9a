"""Keep the libraries' chatter out of stamlane's output, at the source: named messages, nothing else.

Lightning prints device banners ("GPU available: False"), "Seed set to 0", advertising tips for its cloud
products, "Restoring states from the checkpoint path ..." and, for every prediction from a checkpoint trained
with callbacks the prediction does not need, a warning that those callbacks should be given; torch's ``_pytree``
warns about an API Lightning still calls. Three warnings are about what stamlane handles itself: LightningCLI's on
being given arguments (it prints the temporary config path), ModelCheckpoint's "dirpath has changed" on a resume
into a new version folder, the loop's "dataloader is not resumable" (`stamlane.training.resume.ExactResume` makes it so). None of it says anything to a stamlane user. `quiet_libraries` drops
exactly those messages, by logger and text (`CHATTER`) and by warning text (`WARNINGS`): any other message,
a warning of stamlane's own or a new one of a library, still shows. ``stamlane fit|validate|test|predict
--verbose`` keeps everything.
"""

from __future__ import annotations

import logging
import re
import warnings

__all__ = ["CHATTER", "LOGGERS", "WARNINGS", "quiet_libraries"]

LOGGERS = (
    "lightning.pytorch.utilities.rank_zero",
    "lightning.fabric.utilities.rank_zero",
    "lightning.fabric.utilities.seed",
    "lightning.pytorch.trainer.connectors.checkpoint_connector",
)
"""The loggers the chatter comes through."""
CHATTER = re.compile(
    r"^(\N{ELECTRIC LIGHT BULB} Tip|GPU available|TPU available|HPU available|IPU available|Seed set to"
    r"|Restoring states from the checkpoint path|Loaded model weights from the checkpoint"
    r"|Restored all states from the checkpoint|`Trainer\(val_check_interval=|`Trainer.fit` stopped: `max_steps="
    r"|`weights_only` was not set, defaulting to)"
)
"""Log messages dropped: device banners, the seed, advertising tips, checkpoint restore notes, the end of a fit at
its step budget and the validation schedule of one-step smoke runs."""
WARNINGS = (
    r"Be aware that when using `ckpt_path`, callbacks used to create the checkpoint need to be provided",
    r".*isinstance\(treespec, LeafSpec\)` is deprecated",
    # stamlane.cli passes the arguments (with the checkpoint's config, a temporary file) while sys.argv holds the
    # user's own; sys.argv stays as typed so that a DDP rank re-launches the command the user gave
    r"LightningCLI's args parameter is intended to run from within Python",
    # a resumed fit logs and checkpoints into a new version folder; `stamlane.training.fit_report.FitReport` carries the
    # best score of the run it resumed over
    r"The dirpath has changed from .* therefore `best_model_score`",
    # `stamlane.training.resume.ExactResume` replays the interrupted epoch's data: the resume is exact (tested)
    r"You're resuming from a checkpoint that ended before the epoch ended and your dataloader is not resumable",
)
"""Warnings dropped (regular expressions matched at the start of the message), each where stamlane expects it and
has dealt with what it warns about."""


class _DropChatter(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        return not CHATTER.match(str(record.getMessage()))


def quiet_libraries() -> None:
    """Drop `CHATTER` from `LOGGERS` and `WARNINGS` from the warnings (idempotent)."""
    for name in LOGGERS:
        logger = logging.getLogger(name)
        if not any(isinstance(f, _DropChatter) for f in logger.filters):
            logger.addFilter(_DropChatter())
    for message in WARNINGS:
        warnings.filterwarnings("ignore", message=message)
