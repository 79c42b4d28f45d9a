"""The progress bar of long evaluations: tqdm's when it is installed (it is not a dependency), else none."""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from typing import Any


def progress_bar(enabled: bool, total: int, desc: str, unit: str) -> Any | None:
    """A ``tqdm`` bar that clears itself when done, or None (disabled, or tqdm not installed)."""
    if not enabled:
        return None
    try:
        from tqdm import tqdm
    except ImportError:
        return None
    return tqdm(total=total, desc=desc, unit=unit, leave=False)


def sequences_with_progress(
    sequences: Mapping[str, Sequence[object]], enabled: bool, desc: str
) -> Iterator[tuple[str, Sequence[object]]]:
    """``sequences.items()``, a bar over their frames advancing by each sequence's frames once it is scored."""
    bar = progress_bar(enabled, sum(len(frames) for frames in sequences.values()), desc, "frame")
    try:
        for name, frames in sequences.items():
            yield name, frames
            if bar is not None:
                bar.update(len(frames))
    finally:
        if bar is not None:
            bar.close()
