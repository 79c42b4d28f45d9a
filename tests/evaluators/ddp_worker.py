"""One DDP rank for test_eval_torchmetrics: ``python ddp_worker.py RANK WORLD PORT OUT``.

Each rank updates the metrics with its share of the golden images; rank 0 writes the computed values.
"""

from __future__ import annotations

from _golden_data import culane_lanes, tusimple_records
from stamlane_eval.integrations.torchmetrics import CULaneMetric, TuSimpleMetric


def score(rank: int, world: int) -> dict[str, float]:
    """This rank's share of the golden set, scored; the values computed over all ranks."""
    preds, gts = tusimple_records()
    ts = TuSimpleMetric()
    p, g = preds[rank::world], gts[rank::world]
    ts.update([x["lanes"] for x in p], [x["lanes"] for x in g], [x["h_samples"] for x in g], [x["run_time"] for x in p])
    cp, cg = culane_lanes()
    cu = CULaneMetric()
    cu.update(cp[rank::world], cg[rank::world])
    res = {k: float(v) for k, v in {**ts.compute(), **cu.compute()}.items()}
    return res


if __name__ == "__main__":
    from _ddp_rank import run_rank  # imported when run, as in ddp_video_worker (which a test imports)

    run_rank(score)
