"""What the DDP worker scripts share: one gloo rank that scores its share and, on rank 0, writes the values."""

from __future__ import annotations

import json
import os
import sys
from collections.abc import Callable
from pathlib import Path

import torch
import torch.distributed as dist


def run_rank(score: Callable[[int, int], dict[str, float]]) -> None:
    """Run one rank of ``python WORKER RANK WORLD PORT OUT`` (the arguments of `conftest.run_ddp_pair`).

    Args:
        score: ``score(rank, world)`` updates the metrics with this rank's share and returns their computed values
            (synchronised across the ranks); rank 0 writes them to ``OUT`` as json.
    """
    rank, world, port, out = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
    torch.set_num_threads(1)
    os.environ["MASTER_ADDR"], os.environ["MASTER_PORT"] = "127.0.0.1", str(port)
    dist.init_process_group("gloo", rank=rank, world_size=world)
    try:
        res = score(rank, world)
        if rank == 0:
            Path(out).write_text(json.dumps(res))
    finally:
        dist.destroy_process_group()
