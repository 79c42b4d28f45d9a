"""Long evaluations: a progress bar (tqdm's when it is installed; it is not a dependency) and sequences scored
in this process or spread over worker processes."""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Any, TypeVar

R = TypeVar("R")


def progress_bar(enabled: bool, total: int, desc: str, unit: str) -> Any | None:
    """A ``tqdm`` bar that clears itself when done, or None (disabled, or tqdm not installed)."""
    if not enabled:
        return None
    try:
        from tqdm import tqdm
    except ImportError:
        return None
    return tqdm(total=total, desc=desc, unit=unit, leave=False)


def resolve_jobs(jobs: int) -> int:
    """``jobs`` processes, 0 meaning one per core; a negative number is refused."""
    if jobs < 0:
        raise ValueError(f"jobs must be >= 0 (0: one per core), got {jobs}")
    return jobs or os.cpu_count() or 1


def map_sequences(
    score: Callable[[Sequence[Any], str], R],
    sequences: Mapping[str, Sequence[Any]],
    jobs: int = 1,
    progress: bool = False,
    desc: str = "",
) -> list[R]:
    """``score(frames, name)`` of every sequence, in the mapping's order.

    With ``jobs`` > 1 the sequences are scored in that many worker processes (``score`` must then be picklable: a
    module-level function or a ``functools.partial`` of one). A sequence is scored whole by one worker, so its
    result is the one this process would compute; where sequences fail, the error of the first of them in the
    mapping's order is raised, as in this process. The bar advances by each sequence's frames once scored.
    """
    items = list(sequences.items())
    jobs = min(resolve_jobs(jobs), len(items))
    total = sum(len(frames) for _, frames in items)
    if jobs <= 1:
        bar = progress_bar(progress, total, desc, "frame")
        try:
            out = []
            for name, frames in items:
                out.append(score(frames, name))
                if bar is not None:
                    bar.update(len(frames))
            return out
        finally:
            if bar is not None:
                bar.close()
    results: list[Any] = [None] * len(items)
    errors: dict[int, Exception] = {}
    with ProcessPoolExecutor(max_workers=jobs) as pool:
        futures = {pool.submit(score, frames, name): i for i, (name, frames) in enumerate(items)}
        bar = progress_bar(progress, total, desc, "frame")  # after the workers started: none forks a bar's thread
        try:
            for future in as_completed(futures):
                i = futures[future]
                try:
                    results[i] = future.result()
                except Exception as e:  # every sequence is scored, the first in order reported
                    errors[i] = e
                if bar is not None:
                    bar.update(len(items[i][1]))
        except BaseException:  # interrupted: empty the workers' queue
            for future in futures:
                future.cancel()
            raise
        finally:
            if bar is not None:
                bar.close()
    if errors:
        raise errors[min(errors)]
    return results
