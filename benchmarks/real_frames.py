"""The real labelled frames of the real-road check: their label files read and checked, the protocol's split
(docs/real-protocol.md, ``benchmarks/labels/real_split.json``), and the numbers by lane position and by lane count.

**Lane positions** (`positions`): the labelled lines of a frame are placed by where each meets the bottom row of
its frame (its lowest `BOTTOM_POINTS` labelled points extended by a straight line), left or right of the frame's
centre column. Per side, the nearest line to the centre is one of the **ego** pair, the next one **adjacent**, any
further one **outer**. A line is **recalled** when lane.py matches it (`matched_lanes`: its best prediction within
lane.py's 20 px / cos(angle) on `POINT_THRESH` of the rows; no one-to-one assignment, as lane.py), and recall by
position is the recalled lines over the labelled ones of that position, pooled over frames.

**Lane counts** (`count_numbers`): per frame, the predicted lines (what the decoding drew) minus the labelled
ones; their mean absolute value, the frames over- and under-counted, the frames with more than `MAX_LANES`
predicted lines. A label rule that leaves lines out (the video's labels the ego pair and the next line on the left,
none beyond) makes a model that draws more lines over-count: the count is against the labels, not the road.

Intervals: the 95 % percentile bootstrap over frames (`RESAMPLES` resamples, seed `SEED`), given where at least
`MIN_INTERVAL_FRAMES` frames hold the quantity; frames of one video are alike, so the interval is one over these
frames, narrower than the road's variety deserves.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[1]
SPLIT_FILE = REPO / "benchmarks" / "labels" / "real_split.json"
SPLITS = ("dev", "sealed")
POSITIONS = ("ego", "adjacent", "outer")
BOTTOM_POINTS = 5  # the lowest labelled points a line's crossing of the bottom row is extended from
MAX_LANES = 4  # the bound: a highway frame shows at most four lines worth drawing
RESAMPLES = 2000  # bootstrap resamples (stamlane_eval.stats.RESAMPLES)
SEED = 0  # of the resampling: the intervals are a deterministic function of the frames
LEVEL = 0.95
MIN_INTERVAL_FRAMES = 5  # frames holding a quantity for it to get an interval
MAX_LABEL_BYTES = 64 << 20  # a label file larger than this is no label file of a few frames
STRETCHES = (("early", 0, 73), ("middle", 74, 147), ("late", 148, 220))  # the protocol's stretches of the video


class RealFramesError(ValueError):
    """A label or split file that cannot be used as it is (one line, exit status 2)."""


# ------------------------------------------------------------------------------------------------ label files
def read_label_file(path: Path) -> list[dict[str, Any]]:
    """The TuSimple ground-truth records of ``path``, checked as ``stamlane-eval`` checks a ground truth (JSON
    lines, the format's types, finite pixel values, every ``raw_file`` once).

    Raises:
        RealFramesError: naming the file (and the line) and the problem.
    """
    from stamlane_eval.io.files import LaneFileError
    from stamlane_eval.io.tusimple import TuSimpleInputError, check_tusimple, read_tusimple

    from stamlane.safety.guard import GuardError, read_input

    try:
        text = read_input(path, MAX_LABEL_BYTES, "label file")
        records = read_tusimple(path, text=text)
        check_tusimple(records, "gt")
    except GuardError as err:
        raise RealFramesError(str(err)) from None
    except (LaneFileError, TuSimpleInputError) as err:  # read_tusimple's messages name the file, the check's do not
        raise RealFramesError(str(err) if str(err).startswith(str(path)) else f"{path}: {err}") from None
    return records


def frame_file(root: Path, raw_file: str, labels: Path) -> Path:
    """The image a label's ``raw_file`` names under ``root``; refused where the name leads outside ``root`` (an
    absolute name, ``..``, a link out) or can be no file's name.

    Raises:
        RealFramesError: naming the label file and the ``raw_file``.
    """
    from stamlane_eval.io.files import name_problem

    from stamlane.safety.guard import is_inside

    problem = name_problem(raw_file.encode("utf-8", "surrogatepass"))
    if problem is not None:
        raise RealFramesError(f"{labels}: raw_file {raw_file[:80]!r} {problem}")
    path = root / raw_file
    if Path(raw_file).is_absolute() or not is_inside(path, root):
        raise RealFramesError(f"{labels}: raw_file {raw_file[:80]!r} leads outside {root}; it is not read")
    return path


def video_index(raw_file: str, video: str, labels: Path) -> int:
    """The frame index of a video label's ``raw_file`` (``<video>#<frame>``).

    Raises:
        RealFramesError: a ``raw_file`` of another file, or no frame index.
    """
    name, sep, index = raw_file.rpartition("#")
    if not sep or name != video or not index.isdigit() or not index.isascii():
        raise RealFramesError(f"{labels}: raw_file {raw_file[:80]!r} is no frame of {video} ({video}#<frame index>)")
    return int(index)


# ------------------------------------------------------------------------------------------------------ split
def read_split(path: Path = SPLIT_FILE) -> dict[str, Any]:
    """The protocol's split (``{"rule", "dev", "sealed", "rejected", "labels"}``), checked: both splits lists of
    names, no name in both.

    Raises:
        RealFramesError: the file is unreadable, no JSON, or not a split.
    """
    from stamlane.safety.guard import GuardError, read_input

    try:
        split = json.loads(read_input(path, MAX_LABEL_BYTES, "split file"))
    except GuardError as err:
        raise RealFramesError(str(err)) from None
    except ValueError as err:
        raise RealFramesError(f"{path}: not JSON ({err})") from None
    if not isinstance(split, dict) or not all(isinstance(split.get(s), list) for s in SPLITS):
        raise RealFramesError(f"{path}: not a split (an object with the lists {list(SPLITS)})")
    if not isinstance(split.get("labels"), dict):
        raise RealFramesError(f"{path}: not a split (no 'labels' object of label files and their sha256)")
    both = set(map(str, split["dev"])) & set(map(str, split["sealed"]))
    if both:
        raise RealFramesError(f"{path}: {len(both)} frames in both splits, e.g. {sorted(both)[0]!r}")
    return split


def check_split_labels(split: dict[str, Any], key: str, path: Path, records: Sequence[dict], which: str) -> None:
    """Refuse a label file that is not the one the split was made from (its SHA-256), or that names a frame of the
    other split: the sealed frames stay the sealed frames.

    Args:
        split: `read_split`'s.
        key: the label file's name in ``split["labels"]``.
        path: the file read.
        records: its records.
        which: the split its records must all be in.
    """
    from stamlane.safety.guard import file_sha256

    entry = split["labels"].get(key)
    if not isinstance(entry, dict) or "sha256" not in entry:
        raise RealFramesError(f"{SPLIT_FILE.name} names no label file {key}")
    if file_sha256(path) != entry["sha256"]:
        raise RealFramesError(
            f"{path} is not the label file the split was made from (its SHA-256 differs from {SPLIT_FILE.name}'s); "
            "a relabelled frame is a new frame: docs/real-protocol.md"
        )
    names = set(map(str, split[which]))
    stray = [r["raw_file"] for r in records if r["raw_file"] not in names]
    if stray:
        raise RealFramesError(f"{path}: {stray[0]!r} is not a {which} frame of {SPLIT_FILE.name}")


def stretch_of(index: int) -> str:
    """The protocol's stretch of the video (`STRETCHES`) frame ``index`` lies in."""
    for name, _, high in STRETCHES:
        if index <= high:
            return name
    return STRETCHES[-1][0]


# ------------------------------------------------------------------------------------------- lane positions
def bottom_x(xs: Sequence[float], rows: Sequence[float], height: float) -> float | None:
    """Where a labelled line meets the bottom row ``height`` of its frame: its lowest `BOTTOM_POINTS` points extended
    by a least-squares straight line x(y) (its one point's x where it has one); None for a line with no point."""
    points = sorted(((y, x) for x, y in zip(xs, rows, strict=True) if x >= 0), reverse=True)[:BOTTOM_POINTS]
    if not points:
        return None
    ys, xs_ = np.array([p[0] for p in points]), np.array([p[1] for p in points])
    if len(points) == 1 or np.ptp(ys) == 0:
        return float(xs_.mean())
    slope, offset = np.polyfit(ys, xs_, 1)
    return float(slope * height + offset)


def positions(record: dict, width: float, height: float) -> list[str | None]:
    """Per labelled line of ``record`` (its order), its position (`POSITIONS`) in a frame ``width`` x ``height``
    (the labels' pixels); None for a line with no point."""
    crossing = [bottom_x(xs, record["h_samples"], height) for xs in record["lanes"]]
    centre = width / 2
    out: list[str | None] = [None] * len(crossing)
    left = sorted((i for i, x in enumerate(crossing) if x is not None and x < centre), key=lambda i: -crossing[i])  # type: ignore[operator]
    right = sorted((i for i, x in enumerate(crossing) if x is not None and x >= centre), key=lambda i: crossing[i])  # type: ignore[arg-type,return-value]
    for side in (left, right):
        for rank, i in enumerate(side):
            out[i] = POSITIONS[min(rank, len(POSITIONS) - 1)]
    return out


def matched_lanes(pred_lanes: Sequence[Sequence[float]], record: dict) -> list[bool]:
    """Per labelled line of ``record``, whether lane.py matches it among the predicted ``pred_lanes`` (x lists at
    its ``h_samples``).

    lane.py matches each labelled line to its best prediction alone (no one-to-one assignment), so a line's match
    does not depend on the other labelled lines; its rule that more than ``len(gt) + 2`` predictions score the
    frame as missed does: each line is scored among as many copies of itself as the frame has lines."""
    from stamlane_eval.tusimple import evaluate_image

    gt = record["lanes"]
    return [evaluate_image(list(pred_lanes), [lane] * len(gt), record["h_samples"]).matched == len(gt) for lane in gt]


def frame_numbers(pred_lanes: Sequence[Sequence[float]], found: int, record: dict, size: tuple[float, float]) -> dict:
    """One frame's lines by position (labelled, matched) and its count error.

    Args:
        pred_lanes: the predicted lines as x lists at the record's rows (lane.py's input).
        found: the lines the decoding drew on the frame.
        record: the frame's label.
        size: the labels' frame, (width, height) px.
    """
    where = positions(record, *size)
    hit = matched_lanes(pred_lanes, record)
    by = {
        p: [sum(w == p for w in where), sum(w == p and h for w, h in zip(where, hit, strict=True))] for p in POSITIONS
    }
    labelled = sum(w is not None for w in where)
    return {"raw_file": record["raw_file"], "positions": by, "pred_lanes": found, "gt_lanes": labelled}


# ------------------------------------------------------------------------------------------------- intervals
def ratio_interval(num: np.ndarray, den: np.ndarray) -> tuple[list[float] | None, int]:
    """The percentile-bootstrap interval over frames of ``sum(num) / sum(den)`` (per-frame ``num``, ``den``), over
    the resamples whose ``den`` is not 0, and their count; None where fewer than `MIN_INTERVAL_FRAMES` frames have
    ``den`` > 0."""
    num, den = np.asarray(num, dtype=np.float64), np.asarray(den, dtype=np.float64)
    if int((den > 0).sum()) < MIN_INTERVAL_FRAMES:
        return None, 0
    draw = np.random.default_rng(SEED).integers(0, len(num), (RESAMPLES, len(num)))
    top, bottom = num[draw].sum(axis=1), den[draw].sum(axis=1)
    keep = bottom > 0
    tail = (1 - LEVEL) / 2
    low, high = np.quantile(top[keep] / bottom[keep], [tail, 1 - tail])
    return [float(low), float(high)], int(keep.sum())


def f1_interval(per_image: Sequence[dict]) -> list[float] | None:
    """lane.py's F1 over frames (each frame's FP and FN rates, resampled): its 95 % bootstrap interval, or None
    with fewer than `MIN_INTERVAL_FRAMES` frames."""
    from stamlane_eval.stats import bootstrap, f1_of_rates

    if len(per_image) < MIN_INTERVAL_FRAMES:
        return None
    rates = np.array([[i["fp"], i["fn"]] for i in per_image], dtype=np.float64)
    estimate = bootstrap(rates, f1_of_rates, level=LEVEL, resamples=RESAMPLES, seed=SEED)
    return [estimate.low, estimate.high]


def position_recall(frames: Sequence[dict]) -> dict[str, dict]:
    """Recall by position over ``frames`` (`frame_numbers`' dicts): labelled and matched lines, the recall (None
    where no line of the position is labelled), its interval and the frames holding the position."""
    out = {}
    for p in POSITIONS:
        den = np.array([f["positions"][p][0] for f in frames], dtype=np.float64)
        num = np.array([f["positions"][p][1] for f in frames], dtype=np.float64)
        interval, resamples = ratio_interval(num, den)
        out[p] = {
            "labelled": int(den.sum()),
            "matched": int(num.sum()),
            "recall": float(num.sum() / den.sum()) if den.sum() else None,
            "interval": interval,
            "frames": int((den > 0).sum()),
            "resamples": resamples,
        }
    return out


def count_numbers(frames: Sequence[dict]) -> dict[str, Any]:
    """The predicted lines' count against the labelled ones over ``frames`` (`frame_numbers`' dicts)."""
    error = np.array([f["pred_lanes"] - f["gt_lanes"] for f in frames], dtype=np.float64)
    interval, _ = ratio_interval(np.abs(error), np.ones_like(error))
    return {
        "frames": len(frames),
        "mean_abs_error": float(np.abs(error).mean()) if len(error) else None,
        "mean_abs_error_interval": interval,
        "mean_error": float(error.mean()) if len(error) else None,
        "over_counted": int((error > 0).sum()),
        "under_counted": int((error < 0).sum()),
        "exact": int((error == 0).sum()),
        "over_max": int(sum(f["pred_lanes"] > MAX_LANES for f in frames)),
        "max_lanes": MAX_LANES,
    }


def lane_numbers(
    preds: Sequence[dict], found: Sequence[int], records: Sequence[dict], sizes: Sequence[tuple[float, float]]
) -> dict[str, Any]:
    """The numbers by lane position and count of predictions ``preds`` (lane.py's records, one per label of
    ``records``, in order) whose decodings drew ``found`` lines, the labels' frames of ``sizes`` (width, height)."""
    frames = [frame_numbers(p["lanes"], n, r, s) for p, n, r, s in zip(preds, found, records, sizes, strict=True)]
    return {"by_position": position_recall(frames), "counts": count_numbers(frames), "per_frame": frames}


# --------------------------------------------------------------------------- support in the probability map
SUPPORT_COLUMNS = 4  # network columns searched either side of a labelled point: lane.py's 20 px at 1280 px wide, of 256
PRESENT_ROWS = 0.5  # a labelled line is in the probability map where at least this share of its rows has a lane pixel


def label_in_net(xs: Sequence[float], rows: Sequence[float], net_from_orig: np.ndarray) -> np.ndarray:
    """A labelled line's points (lane.py's ``xs`` at ``rows``, -2 where absent) in network-input pixels, ``(N, 2)``
    ``(x, y)`` (``net_from_orig``: the 3x3 map of `stamlane.stream.predictor` outputs)."""
    points = np.array([[x, y, 1.0] for x, y in zip(xs, rows, strict=True) if x >= 0], dtype=np.float64).reshape(-1, 3)
    mapped = np.asarray(net_from_orig, dtype=np.float64) @ points.T
    out: np.ndarray = (mapped[:2] / mapped[2:]).T
    return out


def line_support(
    prob: np.ndarray,
    net_points: np.ndarray,
    prob_thresh: float,
    sure_thresh: float,
    columns: int = SUPPORT_COLUMNS,
) -> dict[str, Any]:
    """How much of one labelled line the lane probability map holds.

    Per labelled point inside the map (``net_points``, `label_in_net`), the largest lane probability on its row
    within ``columns`` network columns of it; then the share of those rows above ``prob_thresh`` (a lane pixel to the
    decoding) and above ``sure_thresh`` (a pixel DBSCAN clusters, the decoding's ``cluster_thresh``), and the mean.

    Args:
        prob: ``(H, W)`` lane probability at network resolution.
        net_points: ``(N, 2)`` ``(x, y)`` of the labelled line in network pixels.
        prob_thresh: the decoding's lane-pixel threshold.
        sure_thresh: the decoding's clustering threshold.
        columns: the half-width of the search, network columns.

    Returns:
        ``{"rows", "lane_rows", "sure_rows", "mean_max", "present"}``: the labelled rows inside the map, the shares
        (None with no row inside), and whether at least `PRESENT_ROWS` of the rows hold a lane pixel.
    """
    if prob.ndim != 2:
        raise ValueError(f"expected prob of shape (H, W), got {prob.shape}")
    height, width = prob.shape
    peaks = []
    for x, y in np.asarray(net_points, dtype=np.float64).reshape(-1, 2):
        row, col = int(np.floor(y)), int(np.rint(x))
        if not (0 <= row < height and -columns <= col < width + columns):
            continue
        lo, hi = max(0, col - columns), min(width, col + columns + 1)
        if lo < hi:
            peaks.append(float(prob[row, lo:hi].max()))
    if not peaks:
        return {"rows": 0, "lane_rows": None, "sure_rows": None, "mean_max": None, "present": False}
    peak = np.array(peaks)
    lane_rows = float((peak > prob_thresh).mean())
    return {
        "rows": len(peaks),
        "lane_rows": lane_rows,
        "sure_rows": float((peak > sure_thresh).mean()),
        "mean_max": float(peak.mean()),
        "present": lane_rows >= PRESENT_ROWS,
    }


CAUSES = ("matched", "absent", "not clustered", "merged", "drawn off the label")
"""Why a labelled line is matched or not: `miss_cause`."""


def miss_cause(matched: bool, present: bool, owner: str) -> str:
    """One labelled line's `CAUSES` entry.

    Args:
        matched: lane.py matches it.
        present: the probability map holds it (`line_support`'s ``present``).
        owner: what the decoding made of the lane pixels along it: ``"noise"`` (no cluster drawn: unassigned, or
            in clusters too small to draw), ``"shared"`` (most of them in a drawn cluster that most pixels of
            another labelled line are in too), ``"own"`` (a drawn cluster of its own).
    """
    if owner not in ("noise", "shared", "own"):
        raise ValueError(f"owner must be noise, shared or own, got {owner!r}")
    if matched:
        return "matched"
    if not present:
        return "absent"
    return {"noise": "not clustered", "shared": "merged", "own": "drawn off the label"}[owner]
