"""Every process's per-image records, in the order of the split, each image once: what makes a score under DDP
the score of one process, to the last bit.

Scoring sums per-image values (TuSimple's accuracies are floats, summed in file order as lane.py does); summed per
process and then across processes, the order of addition, and so the last bits, depend on the number of processes,
and a sampler that pads its shards (PyTorch's ``DistributedSampler`` repeats images until every process has as
many) scores repeated images twice. `gather_records` brings the records of every process together, refuses an
image seen twice and sorts them by the image's key (its index in the split), so that they are scored as one process
scores them.
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence
from typing import Any, Protocol, TypeVar

import torch

__all__ = ["RepeatedImageError", "broadcast_from_zero", "gather_records", "is_distributed", "rank", "world_size"]

T = TypeVar("T")


class SortKey(Hashable, Protocol):
    """What `gather_records` needs of a key: hashable (one image once) and ordered (the order of the split)."""

    def __lt__(self, other: Any, /) -> bool: ...


K = TypeVar("K", bound=SortKey)


class RepeatedImageError(ValueError):
    """An image came twice in one evaluation: a sampler padded its shards (or a split lists it twice)."""


def is_distributed() -> bool:
    """True when a process group of more than one process is running."""
    return torch.distributed.is_available() and torch.distributed.is_initialized() and world_size() > 1


def world_size() -> int:
    return torch.distributed.get_world_size() if torch.distributed.is_initialized() else 1


def rank() -> int:
    return torch.distributed.get_rank() if torch.distributed.is_initialized() else 0


def gather_records(records: Sequence[tuple[K, T]], what: str) -> list[tuple[K, T]]:
    """The records of every process, sorted by key, on every process.

    Args:
        records: this process's ``(key, record)`` pairs; keys sort (ints: the image's index in the split) and name
            one image each.
        what: what is gathered, for the message (``"val scores"``).

    Returns:
        all processes' pairs, sorted by key (one process: its own, sorted).

    Raises:
        RepeatedImageError: a key given twice, by one process or by two: the message names it and the cause.
    """
    merged = list(records)
    if is_distributed():
        parts: list[Any] = [None] * world_size()
        torch.distributed.all_gather_object(parts, merged)
        merged = [pair for part in parts for pair in part]
    seen: set[Hashable] = set()
    for key, _ in merged:
        if key in seen:
            raise RepeatedImageError(
                f"{what}: image {key!r} came twice ({world_size()} processes): the evaluation sampler repeats images "
                f"(PyTorch's DistributedSampler pads its shards); evaluate with a sampler that does not repeat "
                f"(Lightning's UnrepeatedDistributedSampler) or in one process"
            )
        seen.add(key)
    return sorted(merged, key=lambda pair: pair[0])


def broadcast_from_zero(value: T) -> T:
    """Process 0's ``value`` on every process (itself with one process)."""
    if not is_distributed():
        return value
    box = [value]
    torch.distributed.broadcast_object_list(box, src=0)
    return box[0]
