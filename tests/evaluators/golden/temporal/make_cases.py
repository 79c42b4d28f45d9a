"""Write the temporal / video golden cases (inputs only) into a folder: edge-case sequences, then random ones.

    python tests/evaluators/golden/temporal/make_cases.py OUT_DIR [--random-sequences 6] [--frames 10] [--seed 0]

Layout (what RVLD's and MMA-Net's scripts read, through the glue described in ../README.md):
``anno/<seq>/<frame>.lines.txt``, ``pred/<seq>/<frame>.lines.txt`` (CULane text, one lane per line),
``list.txt`` (``<seq>/<frame>`` in time order, sequences contiguous), ``sizes.json`` (entry -> ``[H, W]``),
``tags.json`` (sequence -> what it exercises). The committed golden set is this script's output with the
defaults; the numbers in ``expected.json`` come from the reference scripts, not from this file.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

SMALL = (360, 640)  # (H, W)
MEDIUM = (720, 1280)
LARGE = (1080, 1920)  # most VIL-100 videos


def _fmt(v: float) -> str:
    return f"{v:.3f}".rstrip("0").rstrip(".") if v != int(v) else str(int(v))


def _line(lane: np.ndarray | None) -> str:
    return "" if lane is None or len(lane) == 0 else " ".join(_fmt(float(v)) for v in np.asarray(lane).ravel())


def _lane(x_bottom: float, x_top: float, y_bottom: float, y_top: float, n: int, bend: float = 0.0) -> np.ndarray:
    y = np.linspace(y_bottom, y_top, n)
    s = (y - y_bottom) / (y_top - y_bottom)
    x = x_bottom + (x_top - x_bottom) * s + bend * s * (1 - s)
    return np.stack([x, y], axis=1)


def _shift(lane: np.ndarray, dx: float, dy: float = 0.0) -> np.ndarray:
    return lane + np.array([dx, dy])


A = _lane(150, 290, 359, 150, 8)
B = _lane(490, 350, 359, 150, 8)
C = _lane(320, 320, 359, 160, 6)
FAR = _lane(900, 950, 100, 0, 4)  # right of a 640-wide image: drawn nowhere


def edge_cases() -> list[tuple[str, str, list[tuple[list, list, tuple[int, int]]]]]:
    """(sequence, tag, frames of (anno lanes, pred lanes, (H, W)))."""
    s = SMALL
    u_turn = np.array([[100, 300], [160, 200], [240, 180], [300, 220], [320, 300]], float)  # rows with 2 runs
    dup = np.concatenate([A[:5], A[2:3], A[5:]])  # a point repeated out of order: dict.fromkeys drops it
    cons = np.repeat(A, 2, axis=0)  # every point twice in a row
    neg = _lane(-20.5, 60.7, 359, 150, 7)  # negative x: truncation toward zero
    cases = [
        ("e_perfect", "predictions equal the annotations", [([A, B, C], [A, B, C], s)] * 3),
        (
            "e_miss_middle",
            "a lane missed in the middle frame: two jumps",
            [([A, B], [A, B], s), ([A, B], [B], s), ([A, B], [A, B], s)],
        ),
        (
            "e_empty_pred",
            "an empty prediction file: every annotation IoU 0 there",
            [([A, B], [A, B], s), ([A, B], [], s), ([A, B], [], s)],
        ),
        (
            "e_empty_anno",
            "a frame without annotations breaks the chain",
            [([A, B], [A, B], s), ([], [A], s), ([A, B], [A, B], s)],
        ),
        ("e_both_empty", "frames with neither lanes nor predictions", [([], [], s), ([], [], s), ([A], [A], s)]),
        ("e_single_frame", "a one-frame sequence has no pair", [([A, B], [A], s)]),
        (
            "e_short_lanes",
            "1-point lanes and blank lines are dropped (indices shift)",
            [
                ([A, np.array([[5.0, 5.0]]), None, B], [None, A, np.array([[300.0, 200.0]]), B], s),
                ([None, A, B], [A, None, B], s),
            ],
        ),
        (
            "e_dup_points",
            "repeated points, out of order and consecutive",
            [([dup, cons], [cons, dup], s), ([dup, B], [A, B], s)],
        ),
        (
            "e_two_three_points",
            "2-point (k=1) and 3-point (k=2) lanes",
            [
                ([A[[0, -1]], B[[0, 3, -1]]], [A[[0, -1]], B[[0, 4, -1]]], s),
                ([A[[0, -1]], B[[0, 3, -1]]], [A[[1, -1]], B], s),
            ],
        ),
        (
            "e_outside",
            "lanes entirely outside the image: IoU 0 (the eps), never paired",
            [([FAR, A], [FAR, A], s), ([FAR, A], [FAR, A], s)],
        ),
        (
            "e_partly_outside",
            "lanes leaving the image",
            [
                ([_shift(A, -200), _shift(B, 250)], [_shift(A, -195), _shift(B, 240)], s),
                ([_shift(A, -205), _shift(B, 255)], [_shift(A, -190), _shift(B, 262)], s),
            ],
        ),
        (
            "e_lane_appears",
            "the lane count changes between frames",
            [([A], [A], s), ([A, B], [A, B], s), ([A, B, C], [B, C], s), ([B], [B, C], s)],
        ),
        (
            "e_lanes_move_far",
            "annotations move so far that no pair has IoU > 0.5",
            [([A, B], [A, B], s), ([_shift(A, 60), _shift(B, -60)], [A, B], s)],
        ),
        (
            "e_more_preds",
            "more predictions than annotations",
            [([A], [B, _shift(A, 3), A, C], s), ([A], [_shift(A, 5), C], s)],
        ),
        (
            "e_more_annos",
            "more annotations than predictions: some get no prediction",
            [([A, B, C], [C], s), ([A, B, C], [_shift(C, 8), A], s)],
        ),
        (
            "e_near_thresholds",
            "shifts that put IoUs near 0.5 and 0.8",
            [
                ([A, B, C], [_shift(A, 3), _shift(B, 9), _shift(C, 10)], s),
                ([A, B, C], [_shift(A, 10), _shift(B, 3), _shift(C, 9)], s),
                ([A, B, C], [_shift(A, 4), _shift(B, 11), _shift(C, 2)], s),
            ],
        ),
        (
            "e_size_change",
            "frame sizes change: t-1 is drawn at t's size",
            [
                ([_shift(A, 300, 300), B], [_shift(A, 300, 300), B], MEDIUM),
                ([_shift(A, 300, 300), B], [_shift(A, 305, 300), B], s),
                ([_shift(A, 300, 300), B], [_shift(A, 300, 300), B], MEDIUM),
            ],
        ),
        (
            "e_u_turn",
            "a lane that turns back: rows with two runs of pixels",
            [
                ([u_turn, B], [_shift(u_turn, 4), B], s),
                ([_shift(u_turn, 2), B], [u_turn, _shift(B, 12)], s),
                ([u_turn, C], [_shift(u_turn, 20), C], s),
            ],
        ),
        (
            "e_crossing",
            "lanes that cross",
            [
                ([A, _lane(290, 150, 359, 150, 8)], [A, _lane(292, 150, 359, 150, 8)], s),
                ([A, _lane(290, 150, 359, 150, 8)], [_lane(290, 150, 359, 150, 8), A], s),
            ],
        ),
        (
            "e_negative_x",
            "negative coordinates (truncation toward zero)",
            [([neg, B], [_shift(neg, -0.5), B], s), ([neg, B], [_shift(neg, 0.4), B], s)],
        ),
        (
            "e_reversed_order",
            "prediction points from top to bottom",
            [([A, B], [A[::-1], B[::-1]], s), ([A, B], [A[::-1], _shift(B, 7)[::-1]], s)],
        ),
        (
            "e_large",
            "VIL-100 size, 60-point lanes, .3f predictions",
            [
                (
                    [_lane(400, 900, 1079, 560, 60, 40), _lane(1500, 1000, 1079, 560, 60, -30)],
                    [_lane(404.123, 902.5, 1079, 560, 100, 38), _lane(1490.5, 1003.25, 1079, 560, 100, -25)],
                    LARGE,
                ),
                (
                    [_lane(410, 902, 1079, 560, 60, 40), _lane(1495, 1001, 1079, 560, 60, -30)],
                    [_lane(460.0, 940.0, 1079, 560, 100, 38)],
                    LARGE,
                ),
            ],
        ),
    ]
    return cases


def random_cases(n_seq: int, n_frames: int, seed: int) -> list[tuple[str, str, list]]:
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n_seq):
        size = [SMALL, SMALL, MEDIUM, SMALL][k % 4]
        h, w = size
        n_lanes = int(rng.integers(2, 6))
        noise = float(rng.choice([1.0, 4.0, 8.0, 14.0]))  # how far predictions stray: IoUs spread over 0..1
        lanes = []
        for _ in range(n_lanes):
            xb = rng.uniform(-0.1 * w, 1.1 * w)
            lanes.append([xb, w / 2 + rng.uniform(-0.15, 0.15) * w, rng.uniform(-0.2, 0.2) * w, rng.integers(6, 16)])
        frames = []
        for _ in range(n_frames):
            anno, pred = [], []
            for lane in lanes:
                lane[0] += rng.normal(0, 0.02 * w)  # the road moves
                lane[1] += rng.normal(0, 0.005 * w)
                y_top = h * rng.uniform(0.35, 0.5)
                pts = _lane(lane[0], lane[1], h - 1, y_top, int(lane[3]), lane[2])
                if rng.random() < 0.08:
                    continue  # the annotator skipped this lane in this frame
                anno.append(np.round(pts, int(rng.choice([0, 1]))))
                if rng.random() < 0.12:
                    continue  # the model missed it
                n = int(rng.integers(3, 20))
                p = _lane(
                    lane[0] + rng.normal(0, noise),
                    lane[1] + rng.normal(0, noise),
                    h - 1 - rng.uniform(0, 20),
                    y_top + rng.uniform(-10, 30),
                    n,
                    lane[2] + rng.normal(0, noise),
                )
                pred.append(np.round(p, 3))
            if rng.random() < 0.15:
                pred.append(np.round(_lane(rng.uniform(0, w), rng.uniform(0, w), h - 1, h * 0.45, 10), 3))
            order = rng.permutation(len(pred))
            frames.append((anno, [pred[i] for i in order], size))
        out.append((f"r_{k:02d}", f"random, {n_lanes} lanes, prediction noise {noise:g} px", frames))
    return out


def outcome_cases() -> dict[str, tuple[str, list[tuple[str, str, list]]]]:
    """Whole small datasets on which the reference fails or nearly does: name -> (tag, sequences)."""
    s = SMALL
    one = np.array([[200.0, 300.0], [200.0, 300.0]])  # two points, one place: splprep gets k = 0
    normal = ("n", "a normal pair", [([A, B], [A, B], s), ([A, B], [A], s)])
    return {
        "one_point_anno_in_pair": (
            "a one-point annotation in a 2-frame sequence",
            [("s", "", [([A, one], [A], s), ([A], [A], s)])],
        ),
        "one_point_anno_alone": (
            "a one-point annotation in a 1-frame sequence without predictions",
            [("a", "", [([A, one], [], s)]), normal],
        ),
        "one_point_pred_no_anno": (
            "a one-point prediction in a frame without annotations",
            [("a", "", [([], [one, A], s), ([A], [A], s)]), normal],
        ),
        "one_point_pred_with_anno": (
            "a one-point prediction in a frame with annotations",
            [("a", "", [([A], [one, A], s), ([A], [A], s)])],
        ),
        "no_pair": (
            "only one-frame sequences: Ns + Nj + Nm = 0",
            [("a", "", [([A], [A], s)]), ("b", "", [([B], [B], s)])],
        ),
        "no_matched_pair": (
            "annotations move too far between frames: Ns + Nj + Nm = 0",
            [("a", "", [([A], [A], s), ([_shift(A, 80)], [A], s)])],
        ),
        "no_true_positive": (
            "no prediction anywhere: the video metrics' TP = 0",
            [("a", "", [([A, B], [], s), ([A], [], s)])],
        ),
    }


def write(root: Path, cases: list[tuple[str, str, list]]) -> None:
    entries, sizes, tags = [], {}, {}
    for seq, tag, frames in cases:
        tags[seq] = tag
        for i, (anno, pred, size) in enumerate(frames):
            entry = f"{seq}/{i:05d}"
            entries.append(entry)
            sizes[entry] = list(size)
            for kind, lanes in (("anno", anno), ("pred", pred)):
                path = root / kind / seq / f"{i:05d}.lines.txt"
                path.parent.mkdir(parents=True, exist_ok=True)
                path.write_text("".join(_line(lane) + "\n" for lane in lanes))
    (root / "list.txt").write_text("".join(e + "\n" for e in entries))
    (root / "sizes.json").write_text(json.dumps(sizes, indent=0) + "\n")
    (root / "tags.json").write_text(json.dumps(tags, indent=1) + "\n")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--random-sequences", type=int, default=6)
    ap.add_argument("--frames", type=int, default=10)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--outcomes", action="store_true", help="write outcome_cases() as OUT/<name>/ instead")
    args = ap.parse_args()
    if args.outcomes:
        for name, (_, cases) in outcome_cases().items():
            write(args.out / name, cases)
    else:
        write(args.out, edge_cases() + random_cases(args.random_sequences, args.frames, args.seed))


if __name__ == "__main__":
    main()
