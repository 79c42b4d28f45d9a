"""One DDP rank for test_eval_torchmetrics: ``python ddp_worker.py RANK WORLD PORT OUT``.

Each rank updates the metrics with its share of the golden images; rank 0 writes the computed values.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import torch
import torch.distributed as dist
from _golden_data import culane_lanes, tusimple_records
from stamlane_eval.integrations.torchmetrics import CULaneMetric, TuSimpleMetric


def run(rank: int, world: int, port: int, out: str) -> None:
    torch.set_num_threads(1)
    os.environ["MASTER_ADDR"], os.environ["MASTER_PORT"] = "127.0.0.1", str(port)
    dist.init_process_group("gloo", rank=rank, world_size=world)
    try:
        preds, gts = tusimple_records()
        ts = TuSimpleMetric()
        p, g = preds[rank::world], gts[rank::world]
        ts.update(
            [x["lanes"] for x in p], [x["lanes"] for x in g], [x["h_samples"] for x in g], [x["run_time"] for x in p]
        )
        cp, cg = culane_lanes()
        cu = CULaneMetric()
        cu.update(cp[rank::world], cg[rank::world])
        res = {k: float(v) for k, v in {**ts.compute(), **cu.compute()}.items()}
        if rank == 0:
            Path(out).write_text(json.dumps(res))
    finally:
        dist.destroy_process_group()


if __name__ == "__main__":
    run(int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), sys.argv[4])
