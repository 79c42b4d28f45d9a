"""Frame-to-frame numbers of the lanes a model draws on a video, for `benchmarks/real_roads.py`: lanes that cross
(`crossings`) and how stable the lanes are from one frame to the next (`stability`). Lanes are ``(N, 2)`` point
arrays ``(x, y)`` in the video's pixels."""

from __future__ import annotations

import numpy as np

MATCH_PX = 0.05  # a lane matches the previous frame's nearest lane within this fraction of the frame width
MIN_COMMON_ROWS = 3  # rows two lanes must share to be compared


def _xs(lanes: list[np.ndarray], rows: np.ndarray) -> np.ndarray:
    """``(N, R)`` x of each lane at ``rows`` (NaN where the lane does not reach the row)."""
    from stamlane_eval.tusimple import lanes_to_xs

    xs = np.asarray(lanes_to_xs(lanes, rows), dtype=np.float64).reshape(len(lanes), len(rows))
    xs[xs < 0] = np.nan
    return xs


def crossings(lanes: list[np.ndarray], rows: np.ndarray) -> int:
    """Pairs of lanes of one frame that cross: their left-right order differs between two rows they share."""
    xs = _xs(lanes, rows)
    count = 0
    for i in range(len(xs)):
        for j in range(i + 1, len(xs)):
            d = xs[i] - xs[j]
            d = d[np.isfinite(d)]
            if d.size >= 2 and d.min() < 0 < d.max():
                count += 1
    return count


def stability(frames: list[list[np.ndarray]], rows: np.ndarray, width: int) -> dict[str, float]:
    """Frame-to-frame stability of the lanes of consecutive frames.

    Each lane of a frame is matched to the previous frame's lane nearest to it (mean |dx| over the rows both reach,
    at least `MIN_COMMON_ROWS`), greedily by distance, one to one, within ``MATCH_PX * width``.

    Returns:
        ``count_changes``: frames whose lane count differs from the previous frame's; ``jitter_px``: mean |dx| of the
        matched lanes (px, original frame); ``jitter_px_median``; ``matched``: fraction of a frame's lanes matched to
        one of the previous frame's (1.0: every lane continues); ``unmatched_per_frame``: lanes that appear or jump.
    """
    changes, jitter, matched, total = 0, [], 0, 0
    previous: np.ndarray | None = None
    for lanes in frames:
        xs = _xs(lanes, rows)
        if previous is not None:
            changes += len(xs) != len(previous)
            pairs = []
            for i in range(len(xs)):
                for j in range(len(previous)):
                    common = np.isfinite(xs[i]) & np.isfinite(previous[j])
                    if common.sum() >= MIN_COMMON_ROWS:
                        pairs.append((float(np.abs(xs[i][common] - previous[j][common]).mean()), i, j))
            used_i, used_j = set(), set()
            for d, i, j in sorted(pairs):
                if d <= MATCH_PX * width and i not in used_i and j not in used_j:
                    used_i.add(i)
                    used_j.add(j)
                    jitter.append(d)
            matched += len(used_i)
            total += len(xs)
        previous = xs
    pairs_seen = max(len(frames) - 1, 1)
    return {
        "count_changes": changes,
        "jitter_px": float(np.mean(jitter)) if jitter else float("nan"),
        "jitter_px_median": float(np.median(jitter)) if jitter else float("nan"),
        "matched": matched / total if total else float("nan"),
        "unmatched_per_frame": (total - matched) / pairs_seen,
    }
