"""Golden inputs as in-memory lanes, shared by the integration tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from stamlane_eval.io import culane_entries, culane_lines_path, read_culane_lines, read_tusimple

GOLDEN = Path(__file__).parent / "golden"


def tusimple_records() -> tuple[list[dict], list[dict]]:
    """(preds, gts) in the same order (the golden gt lists each image once)."""
    preds = read_tusimple(GOLDEN / "tusimple_pred.json")
    gts = {g["raw_file"]: g for g in read_tusimple(GOLDEN / "tusimple_gt.json")}
    return preds, [gts[p["raw_file"]] for p in preds]


def culane_lanes() -> tuple[list[list[np.ndarray]], list[list[np.ndarray]]]:
    root = GOLDEN / "culane"
    entries = culane_entries(root / "anno", root / "list.txt")
    preds = [read_culane_lines(culane_lines_path(root / "pred", e)) for e in entries]
    gts = [read_culane_lines(culane_lines_path(root / "anno", e)) for e in entries]
    return preds, gts


def xs_to_points(lanes: list[list[float]], h_samples: list[float]) -> list[np.ndarray]:
    h = np.asarray(h_samples, dtype=np.float64)
    out = []
    for lane in lanes:
        xs = np.asarray(lane, dtype=np.float64)
        out.append(np.stack([xs[xs >= 0], h[xs >= 0]], axis=1))
    return out
