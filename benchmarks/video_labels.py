"""TuSimple labels for frames of the real video, made by a written rule and a classical fit, so that the real-road
check can score the video with lane.py: there the 4-frame models see each labelled frame's real history.

    python benchmarks/video_labels.py [--shared ../shared] [--frames 11 33 ...] [--out benchmarks/labels/...json]
                                      [--pictures outputs/bench/video-labels]

**The rule** (written before any model was scored on these frames): label the painted lines that bound the ego lane
and the lanes beside it, TuSimple's convention ("the current lane and the left/right lanes"). On this highway, the
car drives in the rightmost lane: the solid edge line on its right, the dashed line on its left and the next dashed
line further left; three lines on every labelled frame. The curb, the concrete barrier and the lines beyond the next
lane are not labelled. A line runs from its farthest visible paint down to the bottom of the frame, through the gaps
between dashes and under the cars that hide it, as TuSimple's annotators draw it.

**The fit** (`label_frame`), in the video's own pixels:

1. paint: the white top-hat of the grey frame with a `TOPHAT_WIDTH` x 1 window (what is brighter than the asphalt on
   both sides of it, narrower than the window);
2. the vanishing point: the point of a grid (`VP_GRID`) through which straight rays collect the most paint;
3. the lines: peaks of the mean paint along the rays through it, one ray per x on the bottom row (`ray_peaks`);
4. each line: per row, the paint-weighted centre of the paint above `PAINT_MIN` in a band around its ray, a quadratic
   x(y) fitted to those centres with the ones farther than `OUTLIER_PX` dropped (`fit_line`); a line is kept with
   paint on at least `MIN_PAINT_ROWS` rows (the painted lines here have 37 to 230, the cars, barrier and curb fewer);
5. the label: the quadratic from the highest row with paint to the frame's bottom (or its side), at TuSimple's rows
   in the frame scaled to TuSimple's 1280 x 720 (``h_samples`` 160, 170, ... 710; lane.py's 20-px threshold is meant
   at that size: ``TUSIMPLE_WIDTH / width``, 4/3 for this 960x540 video).

**The sealed frames** (docs/real-protocol.md): the frames ``i % 4 == 0``, 4-220, at least 3 frames from a dev frame,
labelled by the same rule and fit, ``--frames 4 8 16 ... 220 --out benchmarks/labels/solidWhiteRight-sealed.json``;
each looked at before any model ran on it, frames 64 and 220 rejected by the protocol's rule 1 (two lines: the next
dashed line on the left not found) and left out of the file (``benchmarks/labels/real_split.json`` lists them).

Every frame's picture (``--pictures DIR``: paint used in green, the label in yellow, the vanishing point in red; and
``sheet.jpg``, the ten at half size) was looked at; no label was corrected by hand. Writes the labels as json lines (``raw_file`` ``<video>#<frame>``, lanes
in TuSimple's 1280 x 720 pixels) atomically; exit status 2 with one line where the video is missing or unreadable, a
frame index is negative, past the video's end or given twice, or ``--out`` is a folder, no ``.json`` name, an
existing file that is no TuSimple label file, or inside the data.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from _harness import fail, write_image

REPO = Path(__file__).resolve().parents[1]
VIDEO = "data/real/solidWhiteRight.mp4"  # under --shared
LABELS = REPO / "benchmarks" / "labels" / "solidWhiteRight.json"
FRAMES = tuple(range(11, 221, 22))  # ten frames spread over the 221, none of the first few (their history is short)
TUSIMPLE_WIDTH = 1280  # lane.py's frames are 1280 x 720
H_SAMPLES = tuple(range(160, 720, 10))  # TuSimple's rows, in its 720-row frame
TOPHAT_WIDTH = 31  # px: wider than a painted line up close (~20 px here), narrower than a lane
VP_GRID = (range(440, 530, 4), range(296, 340, 3))  # x, y candidates of the vanishing point, px
RAY_X_BOTTOM = range(-1500, 2500, 4)  # where a ray through the vanishing point meets the bottom row, px
RAY_SKIP = 20  # rows below the vanishing point a ray starts (the clutter of distant cars)
RAY_MIN_ROWS = 20  # rows a ray must have inside the frame to be scored
PAINT_CLIP = 80.0  # top-hat values above this count as this much (one glint does not make a line)
PEAK_MIN = 6.0  # mean top-hat along a ray to be a line candidate
PEAK_GAP = 120  # px at the bottom row between two lines' rays
BAND = 14.0  # px: half-width of a line's search band at the bottom row, 30 % of it at the vanishing point
PAINT_MIN = 25.0  # top-hat value of paint
OUTLIER_PX = 4.0  # px from the fitted quadratic: dropped
MIN_PAINT_ROWS = 35  # rows with paint to be a painted line
SHEET_TOP = 0.52  # the contact sheet shows each frame below this fraction of its height (the road)
MAX_OUT_BYTES = 64 << 20  # an existing --out larger than this is no label file of a few frames


class VideoLabelsError(Exception):
    """A missing or unreadable video (one line, exit status 2)."""


@dataclass(frozen=True)
class Line:
    """One labelled line of a frame: ``x = polyval(coeffs, y)`` in the video's pixels, from row ``y_top`` down."""

    coeffs: tuple[float, float, float]
    y_top: float
    paint: np.ndarray  # (N, 2) the paint centres (x, y) it was fitted to


def read_frames(path: Path, wanted: set[int]) -> dict[int, np.ndarray]:
    """The frames of the video at the indices ``wanted``, BGR."""
    capture = cv2.VideoCapture(str(path))
    if not capture.isOpened():
        raise VideoLabelsError(f"cannot read {path}")
    out, index = {}, 0
    while len(out) < len(wanted):
        ok, frame = capture.read()
        if not ok:
            break
        if index in wanted:
            out[index] = frame
        index += 1
    capture.release()
    missing = sorted(wanted - out.keys())
    if missing:
        raise VideoLabelsError(f"{path} has {index} frames; frames {missing} do not exist")
    return out


def paint_of(image: np.ndarray) -> np.ndarray:
    """The white top-hat of the grey frame, (H, W) float32: bright, narrow things (paint) high, the asphalt 0."""
    grey = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY).astype(np.float32)
    window = cv2.getStructuringElement(cv2.MORPH_RECT, (TOPHAT_WIDTH, 1))
    return cv2.morphologyEx(grey, cv2.MORPH_TOPHAT, window)


def _ray_x(vp: tuple[float, float], x_bottom: float | np.ndarray, ys: np.ndarray, height: int) -> np.ndarray:
    return vp[0] + (x_bottom - vp[0]) * (ys - vp[1]) / (height - 1 - vp[1])


def ray_means(paint: np.ndarray, vp: tuple[float, float]) -> np.ndarray:
    """The mean (clipped) paint along each ray from ``vp`` to the bottom row at `RAY_X_BOTTOM`, (len(RAY_X_BOTTOM),)."""
    height, width = paint.shape
    ys = np.arange(int(vp[1] + RAY_SKIP), height)
    xs = _ray_x(vp, np.asarray(RAY_X_BOTTOM, dtype=np.float64)[:, None], ys[None, :], height)  # (rays, rows)
    inside = (xs >= 0) & (xs < width - 1)
    values = paint[ys[None, :], np.round(np.where(inside, xs, 0)).astype(int)].clip(0, PAINT_CLIP)
    rows = inside.sum(axis=1)
    means = (values * inside).sum(axis=1) / np.maximum(rows, 1)
    return np.where(rows >= RAY_MIN_ROWS, means, 0.0)


def vanishing_point(paint: np.ndarray) -> tuple[float, float]:
    """The point of `VP_GRID` whose 40 best rays collect the most paint."""
    best = max((np.sort(ray_means(paint, (x, y)))[-40:].sum(), x, y) for x in VP_GRID[0] for y in VP_GRID[1])
    return float(best[1]), float(best[2])


def ray_peaks(means: np.ndarray) -> list[float]:
    """The bottom-row x of the rays that are line candidates: greedy maxima above `PEAK_MIN`, `PEAK_GAP` apart."""
    chosen: list[int] = []
    for i in np.argsort(means)[::-1]:
        if means[i] < PEAK_MIN:
            break
        if all(abs(RAY_X_BOTTOM[i] - RAY_X_BOTTOM[j]) > PEAK_GAP for j in chosen):
            chosen.append(int(i))
    return sorted(float(RAY_X_BOTTOM[i]) for i in chosen)


def fit_line(paint: np.ndarray, vp: tuple[float, float], x_bottom: float) -> Line | None:
    """The quadratic of the paint around the ray from ``vp`` to ``x_bottom``; None with paint on too few rows."""
    height, width = paint.shape
    centres = []
    for y in range(int(vp[1] + 8), height):
        x_ray = float(_ray_x(vp, x_bottom, np.array([y]), height)[0])
        half = BAND * (0.3 + 0.7 * (y - vp[1]) / (height - vp[1]))
        lo, hi = int(max(0, x_ray - half)), int(min(width - 1, x_ray + half))
        if hi <= lo:
            continue
        row = paint[y, lo : hi + 1]
        on = row > PAINT_MIN
        if on.sum() >= 2:
            xs = np.arange(lo, hi + 1)[on]
            centres.append((float((xs * row[on]).sum() / row[on].sum()), float(y)))
    if len(centres) < MIN_PAINT_ROWS:
        return None
    points = np.array(centres)
    keep = np.ones(len(points), dtype=bool)
    for _ in range(4):
        coeffs = np.polyfit(points[keep, 1], points[keep, 0], 2)
        keep = np.abs(np.polyval(coeffs, points[:, 1]) - points[:, 0]) < OUTLIER_PX
        if keep.sum() < MIN_PAINT_ROWS:
            return None
    coeffs = np.polyfit(points[keep, 1], points[keep, 0], 2)
    a, b, c = (float(v) for v in coeffs)
    return Line((a, b, c), float(points[keep, 1].min()), points[keep])


def label_frame(image: np.ndarray) -> tuple[tuple[float, float], list[Line]]:
    """The vanishing point and the painted lines of a frame, left to right."""
    paint = paint_of(image)
    vp = vanishing_point(paint)
    lines = [fit_line(paint, vp, x) for x in ray_peaks(ray_means(paint, vp))]
    found = [line for line in lines if line is not None]
    return vp, sorted(found, key=lambda line: float(np.polyval(line.coeffs, image.shape[0] - 1)))


def tusimple_record(raw_file: str, lines: list[Line], width: int) -> dict:
    """The lines as a TuSimple record in the frame scaled to `TUSIMPLE_WIDTH` (``-2`` above a line's top and where it
    leaves the frame)."""
    scale = TUSIMPLE_WIDTH / width
    lanes = []
    for line in lines:
        xs = []
        for h in H_SAMPLES:
            y = h / scale
            x = float(np.polyval(line.coeffs, y))
            xs.append(round(x * scale, 1) if y >= line.y_top and 0 <= x <= width - 1 else -2)
        lanes.append(xs)
    return {"raw_file": raw_file, "lanes": lanes, "h_samples": list(H_SAMPLES)}


def frame_of(raw_file: str) -> int:
    """The frame index of a label's ``raw_file`` (``<video>#<frame>``)."""
    return int(raw_file.rpartition("#")[2])


def picture(image: np.ndarray, vp: tuple[float, float], lines: list[Line]) -> np.ndarray:
    """The frame with the paint each line was fitted to (green), its label (yellow) and the vanishing point (red)."""
    out = image.copy()
    height, width = image.shape[:2]
    for line in lines:
        for x, y in line.paint.astype(int):
            cv2.circle(out, (int(x), int(y)), 1, (0, 255, 0), -1)
        ys = np.arange(line.y_top, height)
        xs = np.polyval(line.coeffs, ys)
        inside = (xs >= 0) & (xs <= width - 1)
        cv2.polylines(out, [np.stack([xs[inside], ys[inside]], 1).astype(np.int32)], False, (0, 255, 255), 1)
    cv2.circle(out, (int(vp[0]), int(vp[1])), 4, (0, 0, 255), -1)
    return out


def sheet(pictures: dict[int, np.ndarray], columns: int = 2) -> np.ndarray:
    """The road below the horizon of every picture at half size, ``columns`` a row, each with its frame index."""
    cells = []
    for index, image in pictures.items():
        height, width = image.shape[:2]
        cell = cv2.resize(image[int(SHEET_TOP * height) :], (width // 2, int((1 - SHEET_TOP) * height) // 2))
        cv2.putText(cell, f"frame {index}", (8, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.7, (255, 255, 255), 2)
        cells.append(cell)
    cells += [np.zeros_like(cells[0])] * (-len(cells) % columns)
    return np.vstack([np.hstack(cells[i : i + columns]) for i in range(0, len(cells), columns)])


def label_video(path: Path, frames: tuple[int, ...]) -> tuple[list[dict], dict[int, np.ndarray]]:
    """The TuSimple records of ``frames`` of the video, and each frame's picture."""
    images = read_frames(path, set(frames))
    records, pictures = [], {}
    for index in frames:
        vp, lines = label_frame(images[index])
        records.append(tusimple_record(f"{path.name}#{index}", lines, images[index].shape[1]))
        pictures[index] = picture(images[index], vp, lines)
    return records, pictures


def check_out(out: Path) -> None:
    """Refuse an ``--out`` that is no ``.json`` name, or an existing file that is not a TuSimple label file (a file
    of the user's is never replaced by labels); a folder or a FIFO is `check_outputs`' to refuse."""
    from stamlane_eval.io.files import LaneFileError
    from stamlane_eval.io.tusimple import TuSimpleInputError, check_tusimple, read_tusimple

    from stamlane.safety.guard import GuardError, read_input

    if out.suffix != ".json":
        raise VideoLabelsError(f"--out {out}: the labels are TuSimple json lines; give a name ending in .json")
    if not out.is_file():
        return
    try:
        check_tusimple(read_tusimple(out, text=read_input(out, MAX_OUT_BYTES, "--out")), "gt")
    except (GuardError, LaneFileError, TuSimpleInputError) as err:
        raise VideoLabelsError(
            f"--out {out} exists and is no TuSimple label file ({err}); it is not replaced"
        ) from None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--shared", type=Path, default=REPO.parent / "shared", help="the folder holding data/")
    parser.add_argument("--frames", type=int, nargs="+", default=list(FRAMES), help="frame indices to label")
    parser.add_argument("--out", type=Path, default=LABELS, help="the labels file (json lines)")
    parser.add_argument("--pictures", type=Path, help="write each frame's picture here, to be looked at")
    args = parser.parse_args(argv)
    from stamlane.safety.guard import GuardError, check_outputs, write_atomic

    path = args.shared / VIDEO
    try:
        if not path.is_file():
            raise VideoLabelsError(f"{path} does not exist (the real video lives in ../shared beside the project)")
        if min(args.frames) < 0:
            raise VideoLabelsError(f"--frames takes frame indices >= 0, got {min(args.frames)}")
        twice = sorted({i for i in args.frames if args.frames.count(i) > 1})
        if twice:  # a label file names each frame once (lane.py would score it twice)
            raise VideoLabelsError(f"--frames names frame {twice[0]} more than once: each frame is labelled once")
        check_out(args.out)
        try:  # the labels and pictures may not land on the video or anywhere in the data beside the project
            check_outputs(files=[args.out], folders=[args.pictures], protected=[args.shared])
        except GuardError as err:
            raise VideoLabelsError(str(err)) from None
        records, pictures = label_video(path, tuple(args.frames))
    except VideoLabelsError as err:
        return fail("video_labels", err)
    write_atomic(args.out, "".join(json.dumps(r) + "\n" for r in records))  # json lines, as TuSimple's labels
    if args.pictures is not None:
        named = [(f"{index:04d}", image) for index, image in pictures.items()] + [("sheet", sheet(pictures))]
        for name, image in named:
            write_image(args.pictures / f"{name}.jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 80])
    lanes = [len(r["lanes"]) for r in records]
    print(f"wrote {args.out}: {len(records)} frames, lines per frame {lanes}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
