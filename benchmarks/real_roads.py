"""The real-road check: how a checkpoint does on real labelled frames and on a real highway video.

    python benchmarks/real_roads.py [--ckpt NAME_OR_FILE ...] [--shared ../shared] [--frames N]
                                    [--video-frames N] [--strip 4] [--out outputs/bench/real-roads]

Runs every ``--ckpt`` (default: every shipped model, `stamlane.weights.SHIPPED`) through `StreamingPredictor`,
loaded as ``stamlane stream --ckpt`` loads it (`stamlane.stream.cli.load_predictor`, on the CPU, the model's own
precision, alignment on), on the real data beside the project (``../shared``, never committed):

1. **Labelled frames**: the six 1280x720 highway frames of ``data/frames/`` with their TuSimple labels
   ``data/lanenet_frames.json`` (from the instance masks that come with them). Each frame is its own clip (the
   predictor is reset before it, so the frame is its own history, as ``stamlane predict`` starts a sequence),
   its lanes sampled at the label's ``h_samples`` and scored by lane.py's rules (`stamlane_eval.tusimple.evaluate`,
   no time limit: this shared CPU is no benchmark machine): F1, accuracy, FP, FN, per image too.
2. **Video**: ``data/real/solidWhiteRight.mp4`` (960x540, 221 frames, a California highway whose painted lines do
   not change), streamed frame by frame with history. Per frame, the lanes found; over the video, the histogram of
   lanes per frame, the frames with more than `MAX_LANES` lanes, the lane-count changes from one frame to the
   next, and the lateral jitter of the lanes matched between consecutive frames (`stability`); lane pairs that
   cross each other (`crossings`: two lanes of one frame whose left-right order changes from row to row).
3. **Overlay strip** ``<name>-strip.jpg``: a few video frames with their lanes (top row) and the first labelled
   frames with their labels (yellow bands) under the predictions (bottom row), for a person to look at: what no
   number here says is whether a lane runs through a vehicle.

Writes ``<out>/<name>.json`` and ``<out>/<name>-strip.jpg`` per checkpoint (each atomically) and prints a table;
``<out>/summary.md`` holds the table of every checkpoint of the run. Exit status 2 with one line where
``--shared`` lacks the data or a checkpoint cannot be read.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from collections import Counter
from pathlib import Path
from typing import Any

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
FRAMES_LABELS = "data/lanenet_frames.json"  # under --shared; raw_file is relative to data/
VIDEO = "data/real/solidWhiteRight.mp4"
MAX_LANES = 4  # the bound: a highway frame shows at most four lines worth drawing
MATCH_PX = 0.05  # a lane matches the previous frame's nearest lane within this fraction of the frame width
MIN_COMMON_ROWS = 3  # rows two lanes must share to be compared
STABILITY_ROW_STEP = 10  # px between the rows lanes are compared on
STRIP_CELL = (480, 270)  # W, H of a frame in the overlay strip
STRIP_QUALITY = 80  # JPEG quality of the strip (~200 KB for two rows of four)


class RealRoadsError(Exception):
    """Missing data or an unreadable checkpoint (one line, exit status 2)."""


# ------------------------------------------------------------------------------------------- predictor
def load(ckpt: str) -> Any:
    """A `StreamingPredictor` for ``ckpt`` (a shipped model's name or a checkpoint file), built as ``stamlane stream
    --ckpt CKPT --device cpu`` builds it."""
    from stamlane.stream.cli import StreamError, build_parser, load_predictor

    args = build_parser().parse_args(["unused", "--ckpt", ckpt, "--device", "cpu"])
    try:
        return load_predictor(args)
    except StreamError as err:
        raise RealRoadsError(str(err)) from None


# ------------------------------------------------------------------------------------------- the frames
def read_labels(shared: Path, limit: int | None = None) -> tuple[list[dict], Path]:
    """The TuSimple records of the labelled frames (``limit`` first ones) and the folder their ``raw_file`` is in."""
    path = shared / FRAMES_LABELS
    if not path.is_file():
        raise RealRoadsError(f"{path} does not exist (the real labelled frames live in ../shared beside the project)")
    records = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    return records[:limit] if limit else records, path.parent


def score_frames(predictor: Any, records: list[dict], root: Path) -> tuple[dict, list[list[np.ndarray]]]:
    """lane.py's numbers of the predictor on the labelled frames, each frame its own clip; and the lanes found."""
    from stamlane_eval.tusimple import evaluate, lanes_to_xs

    preds, found = [], []
    for record in records:
        image = cv2.imread(str(root / record["raw_file"]))
        if image is None:
            raise RealRoadsError(f"cannot read {root / record['raw_file']}")
        predictor.reset()
        predictor.y_samples = list(record["h_samples"])
        start = time.perf_counter()
        lanes = predictor(image).lanes
        ms = (time.perf_counter() - start) * 1e3
        found.append(lanes)
        preds.append({"raw_file": record["raw_file"], "lanes": lanes_to_xs(lanes, record["h_samples"]), "run_time": ms})
    predictor.y_samples = None
    result = evaluate(preds, records, time_limit=False)
    per_image = [
        {"raw_file": r["raw_file"], "acc": i.acc, "fp": i.fp, "fn": i.fn, "pred_lanes": i.n_pred, "gt_lanes": i.n_gt}
        for r, i in zip(records, result.per_image, strict=True)
    ]
    numbers = {k: result.as_dict()[k] for k in ("f1", "accuracy", "fp", "fn", "images", "lane_tp", "lane_fp")}
    return numbers | {"per_image": per_image}, found


# -------------------------------------------------------------------------------------------- the video
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


def run_video(predictor: Any, path: Path, max_frames: int | None) -> tuple[dict, list[np.ndarray], list[list]]:
    """Stream the video through the predictor; its numbers, the frames and their lanes."""
    from stamlane.stream.cli import StreamError, iter_frames

    try:
        frames, _, _ = iter_frames(path, max_frames)
        predictor.reset()
        images, found, ms = [], [], []
        for _, image in frames:
            start = time.perf_counter()
            found.append(predictor(image).lanes)
            ms.append((time.perf_counter() - start) * 1e3)
            images.append(image)
    except StreamError as err:
        raise RealRoadsError(str(err)) from None
    height, width = images[0].shape[:2]
    rows = np.arange(height - 1, -1, -STABILITY_ROW_STEP, dtype=np.float64)[::-1]  # every lane's whole length
    counts = [len(lanes) for lanes in found]
    cross = [crossings(lanes, rows) for lanes in found]
    numbers = {
        "video": path.name,
        "frames": len(found),
        "size": f"{width}x{height}",
        "lanes_per_frame": {str(k): v for k, v in sorted(Counter(counts).items())},
        "mean_lanes": float(np.mean(counts)),
        "frames_over_max": sum(c > MAX_LANES for c in counts),
        "max_lanes": MAX_LANES,
        "frames_with_crossing": sum(c > 0 for c in cross),
        "ms_per_frame_median": statistics.median(ms),
    } | stability(found, rows, width)
    return numbers | {"lanes_per_frame_sequence": counts}, images, found


# -------------------------------------------------------------------------------------------- the strip
def strip(
    video: list[np.ndarray],
    video_lanes: list[list],
    labelled: list[np.ndarray],
    labelled_lanes: list[list],
    gt: list[list[np.ndarray]],
    cells: int,
    title: str,
) -> np.ndarray:
    """Two rows of ``cells`` frames: video frames evenly spread (index and lane count written on each), and the first
    labelled frames with their labels under the predictions."""
    from stamlane.predict.overlay import draw_lanes

    def cell(image: np.ndarray, lanes: list, gt_lanes: list | None, text: str) -> np.ndarray:
        drawn = cv2.resize(draw_lanes(image, lanes, gt_lanes), STRIP_CELL, interpolation=cv2.INTER_AREA)
        for colour, width in (((0, 0, 0), 4), ((255, 255, 255), 1)):
            cv2.putText(drawn, text, (8, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.6, colour, width, cv2.LINE_AA)
        return drawn

    blank = np.zeros((*STRIP_CELL[::-1], 3), np.uint8)
    picks = np.linspace(0, len(video) - 1, cells).round().astype(int) if video else []
    top = [
        cell(video[i], video_lanes[i], None, f"{title}  video frame {i}: {len(video_lanes[i])} lanes") for i in picks
    ]
    bottom = [
        cell(image, lanes, truth, f"labelled {k}: {len(lanes)} found, {len(truth)} labelled")
        for k, (image, lanes, truth) in enumerate(zip(labelled, labelled_lanes, gt, strict=True))
    ][:cells]
    rows = [row + [blank] * (cells - len(row)) for row in (top, bottom) if row]
    return np.concatenate([np.concatenate(row, axis=1) for row in rows], axis=0)


def _gt_lanes(record: dict) -> list[np.ndarray]:
    ys = np.asarray(record["h_samples"], dtype=np.float64)
    out = []
    for xs in record["lanes"]:
        xs = np.asarray(xs, dtype=np.float64)
        keep = xs >= 0
        if keep.any():
            out.append(np.stack([xs[keep], ys[keep]], axis=1))
    return out


# ----------------------------------------------------------------------------------------------- report
def check(ckpt: str, shared: Path, frames: int | None, video_frames: int | None, cells: int) -> tuple[dict, np.ndarray]:
    """Every number of the real-road check for one checkpoint, and its overlay strip."""
    records, root = read_labels(shared, frames)
    video = shared / VIDEO
    if not video.is_file():
        raise RealRoadsError(f"{video} does not exist (the real video lives in ../shared beside the project)")
    predictor = load(ckpt)
    frame_numbers, frame_lanes = score_frames(predictor, records, root)
    video_numbers, images, video_lanes = run_video(predictor, video, video_frames)
    labelled = [cv2.imread(str(root / r["raw_file"])) for r in records[:cells]]
    gt = [_gt_lanes(r) for r in records[:cells]]
    picture = strip(images, video_lanes, labelled, frame_lanes[:cells], gt, cells, Path(ckpt).stem)
    result = {
        "checkpoint": ckpt,
        "num_frames": predictor.num_frames,
        "image_size": list(predictor.image_size),
        "crop_top": predictor.transform.crop_top,
        "labelled_frames": frame_numbers,
        "video": video_numbers,
    }
    return result, picture


def table(results: list[dict]) -> str:
    """A markdown table of the headline numbers of each checkpoint."""
    lines = [
        "| checkpoint | TuSimple F1 | accuracy | FP | FN | video: lanes per frame (frames) | > 4 lanes | count changes "
        "| jitter px (median) | crossing frames |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        f, v = r["labelled_frames"], r["video"]
        hist = ", ".join(f"{k}: {n}" for k, n in v["lanes_per_frame"].items())
        lines.append(
            f"| {Path(r['checkpoint']).name} | {100 * f['f1']:.1f} | {100 * f['accuracy']:.1f} | {100 * f['fp']:.1f} "
            f"| {100 * f['fn']:.1f} | {hist} | {v['frames_over_max']} | {v['count_changes']} "
            f"| {v['jitter_px']:.1f} ({v['jitter_px_median']:.1f}) | {v['frames_with_crossing']} |"
        )
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--ckpt", nargs="+", help="shipped model names or checkpoint files (default: every shipped)")
    parser.add_argument("--shared", type=Path, default=REPO.parent / "shared", help="the folder holding data/")
    parser.add_argument("--frames", type=int, help="score only the first N labelled frames")
    parser.add_argument("--video-frames", type=int, help="stream only the first N video frames")
    parser.add_argument("--strip", type=int, default=4, help="frames per row of the overlay strip")
    parser.add_argument("--out", type=Path, default=Path("outputs/bench/real-roads"))
    args = parser.parse_args(argv)
    from stamlane.safety.guard import atomic_path, write_atomic
    from stamlane.training.quiet import quiet_libraries
    from stamlane.weights import SHIPPED

    quiet_libraries()
    for name, value in (("--frames", args.frames), ("--video-frames", args.video_frames), ("--strip", args.strip)):
        if value is not None and value < 1:
            print(f"real_roads: error: {name} must be >= 1, got {value}", file=sys.stderr)
            return 2
    ckpts = args.ckpt or [m.name for m in SHIPPED]
    results, pictures = [], []
    try:
        read_labels(args.shared)  # the data first: a missing folder is said before any model is loaded
        if not (args.shared / VIDEO).is_file():
            raise RealRoadsError(f"{args.shared / VIDEO} does not exist (the real video lives in ../shared)")
        for ckpt in ckpts:
            print(f"real_roads: {ckpt} ...", file=sys.stderr)
            result, picture = check(ckpt, args.shared, args.frames, args.video_frames, args.strip)
            results.append(result)
            pictures.append((Path(ckpt).stem, picture))
    except RealRoadsError as err:
        print(f"real_roads: error: {err}", file=sys.stderr)
        return 2
    args.out.mkdir(parents=True, exist_ok=True)
    for result, (name, picture) in zip(results, pictures, strict=True):
        with atomic_path(args.out / f"{name}-strip.jpg") as tmp:
            cv2.imwrite(str(tmp), picture, [cv2.IMWRITE_JPEG_QUALITY, STRIP_QUALITY])
        write_atomic(args.out / f"{name}.json", json.dumps(result, indent=1) + "\n")
    summary = table(results)
    write_atomic(args.out / "summary.md", summary)
    print(summary, end="")
    print(f"wrote {args.out}/: " + ", ".join(f"{n}.json, {n}-strip.jpg" for n, _ in pictures) + ", summary.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())
