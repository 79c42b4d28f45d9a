"""One DDP rank for the video metrics of test_eval_torchmetrics: ``python ddp_video_worker.py RANK WORLD PORT OUT``.

Rank r scores every other sequence of the golden temporal set (whole sequences: RVLD's pairs stay on one
process) and every other frame for the MMA-Net metric (a sequence split between processes); rank 0 writes the
computed values.
"""

from __future__ import annotations

import json
from pathlib import Path

from stamlane_eval.integrations.torchmetrics import TemporalStabilityMetric, VideoMetric
from stamlane_eval.io import read_culane_lines

GOLDEN = Path(__file__).parent / "golden" / "temporal"


def golden_frames() -> list[tuple[str, list, list, tuple[int, int]]]:
    """(sequence, preds, annos, (H, W)) per frame of the golden temporal set, in list order."""
    sizes = json.loads((GOLDEN / "sizes.json").read_text())
    out = []
    for entry in (GOLDEN / "list.txt").read_text().split():
        pred = read_culane_lines(GOLDEN / "pred" / f"{entry}.lines.txt")
        anno = read_culane_lines(GOLDEN / "anno" / f"{entry}.lines.txt")
        out.append((entry.rsplit("/", 1)[0], pred, anno, tuple(sizes[entry])))
    return out


def score(rank: int, world: int) -> dict[str, float]:
    """This rank's share of the golden set, scored; the values computed over all ranks."""
    frames = golden_frames()
    names = sorted({f[0] for f in frames})
    mine = [f for f in frames if names.index(f[0]) % world == rank]
    tm = TemporalStabilityMetric()
    tm.update([f[1] for f in mine], [f[2] for f in mine], [f[0] for f in mine], [f[3] for f in mine])
    vm = VideoMetric()
    split = frames[rank::world]
    vm.update([f[1] for f in split], [f[2] for f in split], [f[0] for f in split], [f[3] for f in split])
    res = {f"temporal_{k}": float(v) for k, v in tm.compute().items()}
    res.update({f"video_{k}": float(v) for k, v in vm.compute().items()})
    return res


if __name__ == "__main__":
    from _ddp_rank import run_rank  # here: test_eval_video_torchmetrics imports this file for its frames

    run_rank(score)
