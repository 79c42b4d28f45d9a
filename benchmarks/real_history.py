"""Real history on a real road: the video's labelled frames with their key frame spoiled, the history left clean.

    python benchmarks/real_history.py [--ckpt NAME_OR_FILE ...] [--kinds none drop glare occluder blank] [--draws 3]
                                      [--frames N] [--shared ../shared] [--out outputs/bench/real-history]

The synthetic ``reveal`` split measures how much a 4-frame model reads its history where the key frame hides the
road. This asks the same on a real road. For each labelled frame of the real video (`real_roads.VIDEO_LABELS`: ten
frames, 22 apart), each kind of `stamlane.data.corruption` and each draw, the key frame is spoiled as training spoils
it (`KeyFrameCorruption` on the whole 960x540 frame, seeded by frame, kind and draw: the same pixels for every
checkpoint), and each checkpoint (default: the shipped ``stam4-dashcam`` and ``single-dashcam``) runs it twice:

- ``history``: the predictor reset, the frame's ``num_frames - 1`` predecessors streamed clean, then the spoiled
  frame; the history is pre-aligned onto it as ``stamlane stream`` aligns (ORB features of the spoiled frame: where
  they fail, the predictor's own fallback);
- ``copies``: the predictor reset and the spoiled frame alone, its history slots copies of it (how a stream starts).
  A single-frame checkpoint runs once: both are the same.

The kinds ``vehicle`` and ``traffic`` (asked for by ``--kinds``) are the paper's case: real vehicles (rear views cut
from ``../shared/data/frames`` by the rectangles of `PATCHES`), `VEHICLES_PER_FRAME` pasted on different lines,
standing on the road plane (`Road`, `placement`: scaled with their row) and moving relative to it (`SPEED_MS` along
the road, up to `LATERAL_MS` across); ``vehicle``: in the key frame alone, the history intact; ``traffic``: in every
frame where they stood then (25 fps). Both share the key frame; `hidden_counts`: the labelled points hidden.

The kind ``none`` (the key frame clean) is the reference. lane.py's F1 per checkpoint, probe and kind, in TuSimple's
1280x720 as `real_roads.score_video_frames` scores it, with a 95 % bootstrap interval over the ten frames (the draws
of a frame resampled together); the history use (``history − copies``) and each checkpoint against the first, paired.
``sheet.jpg``: the middle frame, a row per kind, the first checkpoint's lanes with its history and with copies, the
labels as yellow bands under them.

Exit status 2 with one line where the video or a checkpoint cannot be read or an option is out of range.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from dataclasses import dataclass
from itertools import pairwise
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import real_roads  # a benchmark script beside this one
from _harness import Within, fail, option_problem, write_image, write_result

from stamlane.data.corruption import CORRUPTIONS, KeyFrameCorruption

VEHICLE_KINDS = ("vehicle", "traffic")  # real vehicles pasted over the lines: the key frame alone / every frame
KINDS = ("none", *CORRUPTIONS, *VEHICLE_KINDS)
DEFAULT_KINDS = ("none", *CORRUPTIONS)  # what the committed tables of docs/results/real-history/ were made with
PATCHES = real_roads.REPO / "benchmarks" / "labels" / "real_vehicles.json"  # rectangles in ../shared/data/frames
VEHICLES_PER_FRAME = 2  # vehicles pasted on a frame, each on another labelled line
LANE_WIDTH_M = 3.7  # a US highway lane: the metric scale of the ego lane's two lines
VEHICLE_WIDTH_M = 1.85  # every patch's vehicle, mirror to mirror
HFOV_DEG = 60.0  # the video camera's assumed horizontal field of view (only the vehicles' speeds in pixels need it)
SPEED_MS = (3.0, 15.0)  # range of a vehicle's speed along the road relative to the camera, either way (m/s)
LATERAL_MS = 1.5  # largest lateral speed (m/s): a lane change across the line it covers
NEAREST_M = 2.5  # a vehicle nearer than this (its bottom below the bonnet) is not drawn
SEEDED = re.compile(r"^(?P<recipe>.+)-s(?P<seed>\d+)$")  # a checkpoint of one seed of a recipe
DEFAULT_CKPTS = ("stam4-dashcam", "single-dashcam")
DEFAULT_DRAWS = 3
MAX_DRAWS = 20  # spoils per frame and kind: each is a network pass per probe
MAX_RESAMPLES = 20_000  # the bootstrap holds resamples x images weights (130 images a kind at 3 draws)
SHEET_CELL = (480, 270)


def spoil(image: np.ndarray, kind: str, seed: list[int]) -> np.ndarray:
    """``image`` (BGR uint8) with its key-frame corruption ``kind`` (``none``: unchanged), as training draws it."""
    if kind == "none":
        return image
    clip = np.ascontiguousarray((image[..., ::-1].astype(np.float32) / 255.0).transpose(2, 0, 1)[None])
    KeyFrameCorruption(1.0, (kind,))(clip, np.random.default_rng(seed))
    return np.ascontiguousarray((clip[0].transpose(1, 2, 0)[..., ::-1] * 255.0).round().astype(np.uint8))


def read_frames(path: Path, wanted: set[int]) -> tuple[dict[int, np.ndarray], float]:
    """The video's frames of index in ``wanted`` (BGR uint8) and its frame rate (25 where it records none)."""
    from stamlane.stream.cli import StreamError, iter_frames

    try:
        frames, _, fps = iter_frames(path, max(wanted) + 1)
        images = {i: image for i, (_, image) in enumerate(frames) if i in wanted}
    except StreamError as err:
        raise real_roads.RealRoadsError(str(err)) from None
    if len(images) < len(wanted):
        raise real_roads.RealRoadsError(f"{path} ends before frame {max(wanted)}, which its labels need")
    return images, float(fps or 25.0)


# --------------------------------------------------------------------------------------------- real vehicles
def read_patches(shared: Path) -> list[np.ndarray]:
    """The vehicles of `PATCHES`, cut from the real frames in ``shared/data/frames`` (BGR uint8, rear views)."""
    spec = json.loads(PATCHES.read_text())
    patches = []
    for entry in spec["patches"]:
        path = shared / "data" / "frames" / entry["frame"]
        image = cv2.imread(str(path)) if path.is_file() else None
        if image is None:
            raise real_roads.RealRoadsError(f"{path} cannot be read (the vehicle patches are cut from it)")
        x0, y0, x1, y1 = entry["box"]
        if not (0 <= x0 < x1 <= image.shape[1] and 0 <= y0 < y1 <= image.shape[0]):
            raise real_roads.RealRoadsError(f"{PATCHES.name}: box {entry['box']} lies outside {path}")
        patches.append(image[y0:y1, x0:x1].copy())
    return patches


@dataclass(frozen=True)
class Road:
    """A labelled frame's road, in TuSimple's 1280x720 label pixels: each line as ``x = a y + b`` with its first and
    last labelled rows, the ego lane's vanishing row, the camera's height (metres, from `LANE_WIDTH_M` and how fast
    the ego lane widens down the frame) and its focal length (`HFOV_DEG`)."""

    lines: list[tuple[float, float, float, float]]
    horizon: float
    height: float
    focal: float

    @classmethod
    def of(cls, record: dict) -> Road:
        rows = np.asarray(record["h_samples"], np.float64)
        lines = []
        for lane in record["lanes"]:
            xs = np.asarray(lane, np.float64)
            on = xs >= 0
            if on.sum() >= 2:
                a, b = np.polyfit(rows[on], xs[on], 1)
                lines.append((float(a), float(b), float(rows[on].min()), float(rows[on].max())))
        if len(lines) < 2:
            raise real_roads.RealRoadsError(f"{record['raw_file']}: fewer than two labelled lines, no road to drive on")
        bottom = real_roads.TUSIMPLE_WIDTH * 9 / 16
        lines.sort(key=lambda line: line[0] * bottom + line[1])
        centre = real_roads.TUSIMPLE_WIDTH / 2
        left, right = min(
            pairwise(lines), key=lambda p: abs((p[0][0] + p[1][0]) * bottom / 2 + (p[0][1] + p[1][1]) / 2 - centre)
        )
        widening = right[0] - left[0]  # the ego lane's width grows by this many pixels a row
        horizon = -(right[1] - left[1]) / widening
        focal = real_roads.TUSIMPLE_WIDTH / (2 * np.tan(np.radians(HFOV_DEG) / 2))
        return cls(lines, float(horizon), LANE_WIDTH_M / widening, float(focal))


@dataclass(frozen=True)
class Vehicle:
    """A vehicle on the road at the key frame: on ``line`` (its index in `Road.lines`) ``z`` metres ahead,
    ``offset`` metres right of it, moving ``speed`` m/s away along the road and ``lateral`` m/s to the right;
    ``patch``: its picture (an index of `read_patches`)."""

    line: int
    z: float
    offset: float
    speed: float
    lateral: float
    patch: int


def draw_vehicles(road: Road, rng: np.random.Generator, patches: int) -> list[Vehicle]:
    """`VEHICLES_PER_FRAME` vehicles, each on another line, its bottom on a row drawn over the nearer 70 % of the
    line's labelled rows (so that it hides the line from there up), within 0.3 m of the line."""
    chosen = rng.choice(len(road.lines), size=min(VEHICLES_PER_FRAME, len(road.lines)), replace=False)
    vehicles = []
    for line in (int(i) for i in chosen):
        top, bottom = road.lines[line][2:]
        row = top + float(rng.uniform(0.3, 1.0)) * (bottom - top)
        z = road.focal * road.height / max(row - road.horizon, 1.0)
        speed = float(rng.choice([-1.0, 1.0])) * float(rng.uniform(*SPEED_MS))
        offset, lateral = float(rng.uniform(-0.3, 0.3)), float(rng.uniform(-LATERAL_MS, LATERAL_MS))
        vehicles.append(Vehicle(line, z, offset, speed, lateral, int(rng.integers(patches))))
    return vehicles


def placement(vehicle: Vehicle, road: Road, aspect: float, t: float) -> tuple[float, float, float, float] | None:
    """Where ``vehicle`` stands ``t`` seconds after the key frame (negative: before it): its box ``(x0, y0, x1, y1)``
    in label pixels, the bottom on the ground row of its distance, its width `VEHICLE_WIDTH_M` at that row's scale,
    its height ``aspect`` (height / width of its picture) times that; None nearer than `NEAREST_M`."""
    z = vehicle.z + vehicle.speed * t
    if z < NEAREST_M:
        return None
    scale = road.focal / z  # pixels a metre at its distance
    bottom = road.horizon + road.height * scale
    a, b = road.lines[vehicle.line][:2]
    centre = a * bottom + b + (vehicle.offset + vehicle.lateral * t) * scale
    width = VEHICLE_WIDTH_M * scale
    return centre - width / 2, bottom - aspect * width, centre + width / 2, bottom


def silhouette(height: int, width: int) -> np.ndarray:
    """A vehicle's rear outline in its box, ``(height, width)`` float32 in [0, 1]: the top 40 % (cabin and roof)
    narrowing to 76 % of the width, the edges softened by a pixel."""
    alpha = np.zeros((height, width), np.float32)
    for row in range(height):
        inset = round(0.12 * max(0.0, 1 - row / (0.4 * height)) * width)
        alpha[row, inset : max(width - inset, inset + 1)] = 1.0
    return cv2.GaussianBlur(alpha, (3, 3), 0) if min(height, width) >= 3 else alpha


def _boxes(
    vehicles: list[Vehicle], road: Road, patches: list[np.ndarray], t: float, width: int
) -> list[tuple[Vehicle, int, int, int, int]]:
    """Each vehicle standing at time ``t`` with its box in the pixels of a frame ``width`` wide, far to near."""
    scale = width / real_roads.TUSIMPLE_WIDTH
    out = []
    for vehicle in sorted(vehicles, key=lambda v: -(v.z + v.speed * t)):
        patch = patches[vehicle.patch]
        box = placement(vehicle, road, patch.shape[0] / patch.shape[1], t)
        if box is not None:
            x0, y0, x1, y1 = (round(c * scale) for c in box)
            if x1 - x0 >= 2 and y1 - y0 >= 2:
                out.append((vehicle, x0, y0, x1, y1))
    return out


def paste(image: np.ndarray, vehicles: list[Vehicle], road: Road, patches: list[np.ndarray], t: float) -> np.ndarray:
    """``image`` (BGR uint8, any size of TuSimple's aspect) with ``vehicles`` where they stand at time ``t``, far to
    near, each its picture resized to its box and blended through its `silhouette`; ``image`` is not changed."""
    out = image.astype(np.float32)
    h, w = image.shape[:2]
    for vehicle, x0, y0, x1, y1 in _boxes(vehicles, road, patches, t, w):
        cx0, cy0, cx1, cy1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
        if cx1 <= cx0 or cy1 <= cy0:
            continue
        sprite = cv2.resize(patches[vehicle.patch], (x1 - x0, y1 - y0), interpolation=cv2.INTER_AREA)
        part = (slice(cy0 - y0, cy1 - y0), slice(cx0 - x0, cx1 - x0))
        alpha = silhouette(y1 - y0, x1 - x0)[part][..., None]
        out[cy0:cy1, cx0:cx1] = alpha * sprite[part].astype(np.float32) + (1 - alpha) * out[cy0:cy1, cx0:cx1]
    return np.clip(out.round(), 0, 255).astype(np.uint8)


def cover(
    shape: tuple[int, int], vehicles: list[Vehicle], road: Road, patches: list[np.ndarray], t: float
) -> np.ndarray:
    """Where the vehicles standing at time ``t`` hide the road in a frame of ``shape`` (H, W): bool, the pixels
    of their silhouettes above one half."""
    h, w = shape
    mask = np.zeros((h, w), bool)
    for _, x0, y0, x1, y1 in _boxes(vehicles, road, patches, t, w):
        cx0, cy0, cx1, cy1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
        if cx1 > cx0 and cy1 > cy0:
            alpha = silhouette(y1 - y0, x1 - x0)[cy0 - y0 : cy1 - y0, cx0 - x0 : cx1 - x0]
            mask[cy0:cy1, cx0:cx1] |= alpha > 0.5
    return mask


def hidden_counts(record: dict, masks: list[np.ndarray]) -> list[int]:
    """``[labelled points, hidden in the key frame, of those free in at least one earlier frame]``: the record's
    points (label pixels) looked up in ``masks`` (the earlier frames' covers, oldest first, the key frame's last) at
    the same image point (the camera's own motion over the few frames left out: a line moves little in the image)."""
    h, w = masks[-1].shape
    scale = w / real_roads.TUSIMPLE_WIDTH
    points = hidden = shown = 0
    for lane in record["lanes"]:
        for x, y in zip(lane, record["h_samples"]):
            col, row = round(x * scale), round(y * scale)
            if x < 0 or not (0 <= col < w and 0 <= row < h):
                continue
            points += 1
            if masks[-1][row, col]:
                hidden += 1
                shown += int(any(not m[row, col] for m in masks[:-1]))
    return [points, hidden, shown]


def spoiled_window(
    clean: list[np.ndarray], kind: str, seed: list[int], record: dict, patches: list[np.ndarray], fps: float
) -> list[np.ndarray]:
    """A labelled frame and its predecessors (``clean``, oldest first, the frame last) as the probes see them: the
    frame spoiled by ``kind`` and its history clean; ``vehicle``: real vehicles pasted over its lines (`paste`),
    the history clean; ``traffic``: the same vehicles in every frame where they stood then (``fps``)."""
    if kind not in VEHICLE_KINDS:
        return [*clean[:-1], spoil(clean[-1], kind, seed)]
    road = Road.of(record)
    vehicles = draw_vehicles(road, np.random.default_rng(seed), len(patches))
    depth = len(clean) - 1
    history = [
        paste(image, vehicles, road, patches, -(depth - k) / fps) if kind == "traffic" else image
        for k, image in enumerate(clean[:-1])
    ]
    return [*history, paste(clean[-1], vehicles, road, patches, 0.0)]


def window_covers(
    record: dict, kind: str, seed: list[int], patches: list[np.ndarray], fps: float, depth: int, shape: tuple[int, int]
) -> list[np.ndarray]:
    """What the vehicles of `spoiled_window` hide in each frame of its window (oldest first; `cover`): nothing in the
    history of ``vehicle``, the vehicles where they stood then in that of ``traffic``."""
    road = Road.of(record)
    vehicles = draw_vehicles(road, np.random.default_rng(seed), len(patches))
    times = [-(depth - k) / fps for k in range(depth + 1)]
    return [
        cover(shape, vehicles, road, patches, t) if kind == "traffic" or t == 0 else np.zeros(shape, bool)
        for t in times
    ]


def run_probe(predictor: Any, history: list[np.ndarray], key: np.ndarray) -> list[np.ndarray]:
    """The key frame's lanes (original pixels) after a reset and the ``history`` frames streamed before it."""
    config = {"model": predictor.postprocess}
    predictor.reset()
    for image in history:
        predictor(image)
    return real_roads.lanes_of(predictor, key, config, None)["model"]


def scores(preds: list[dict], records: list[dict], resamples: int) -> dict:
    """lane.py's numbers of ``preds`` and the F1's interval over frames (a record's frame: its ``frame`` key)."""
    from stamlane_eval.stats import bootstrap, f1_of_rates, tusimple_rates
    from stamlane_eval.tusimple import evaluate

    result = evaluate(preds, records, time_limit=False)
    rates = tusimple_rates(result.per_image)
    one = bootstrap(rates, f1_of_rates, groups=[r["frame"] for r in preds], resamples=resamples)
    return {"f1": one.value, "f1_low": one.low, "f1_high": one.high, "fp": result.fp, "fn": result.fn, "rates": rates}


def paired(a: dict, b: dict, frames: list[int], resamples: int) -> dict:
    """``a − b`` of two scorings of the same records, its 95 % interval over frames."""
    from stamlane_eval.stats import f1_of_rates, paired_bootstrap

    diff = paired_bootstrap(a["rates"], b["rates"], f1_of_rates, groups=frames, resamples=resamples)
    return {"diff": diff.value, "low": diff.low, "high": diff.high}


Probe = tuple[str, Any, str]  # (checkpoint name, its predictor, "history" or "copies")


def run(
    ckpts: list[str],
    video: Path,
    kinds: list[str],
    draws: int,
    resamples: int,
    frames: int | None = None,
    patches: list[np.ndarray] | None = None,
) -> tuple[dict, dict[str, np.ndarray]]:
    """Every checkpoint on every spoiled labelled frame (the first ``frames``): the numbers, and the first
    checkpoint's sheet cells; ``patches``: the vehicles of the vehicle kinds (`read_patches`)."""
    records = real_roads.read_video_labels()[:frames]
    names = [Path(ckpt).stem for ckpt in ckpts]  # a file's name without its folder, as real_roads.py names it
    if len(set(names)) < len(names):
        raise real_roads.RealRoadsError(f"two checkpoints of one name among {' '.join(names)}")
    predictors = [real_roads.load(ckpt) for ckpt in ckpts]
    probes = [(c, p, probe) for c, p in zip(names, predictors, strict=True) for probe in ("history", "copies")]
    probes = [(c, p, probe) for c, p, probe in probes if p.num_frames > 1 or probe == "history"]
    preds, scored, sheet, hidden = stream(probes, records, video, kinds, draws, patches or [])
    out: dict[str, Any] = {"video": video.name, "labels": str(real_roads.VIDEO_LABELS.relative_to(real_roads.REPO))}
    out |= {"frames": [real_roads.video_frame(r) for r in records], "draws": draws, "kinds": kinds}
    if hidden:  # the vehicle kinds: labelled points they hide in the key frame, of those free in an earlier frame
        out["hidden_points"] = {k: dict(zip(("points", "hidden", "free_in_history"), v)) for k, v in hidden.items()}
    out["checkpoints"] = {c: {"num_frames": p.num_frames, "kinds": {k: {} for k in kinds}} for c, p, _ in probes}
    results = {key: scores(value, scored[key[2]], resamples) for key, value in preds.items()}
    for (ckpt, probe, kind), value in results.items():
        frames_of = [r["frame"] for r in scored[kind]]
        row = {k: v for k, v in value.items() if k != "rates"}
        if probe == "copies":
            row["history_use"] = paired(results[ckpt, "history", kind], value, frames_of, resamples)
        elif ckpt != names[0]:
            row[f"vs_{names[0]}"] = paired(results[names[0], "history", kind], value, frames_of, resamples)
        out["checkpoints"][ckpt]["kinds"][kind][probe] = row
    out["recipes"] = recipes(results, {k: [r["frame"] for r in v] for k, v in scored.items()}, names, resamples)
    return out, sheet


def stream(
    probes: list[Probe], records: list[dict], video: Path, kinds: list[str], draws: int, patches: list[np.ndarray]
) -> tuple[dict[tuple[str, str, str], list[dict]], dict[str, list[dict]], dict[str, np.ndarray], dict[str, list[int]]]:
    """Every probe on every spoiled labelled frame: lane.py's prediction records per (checkpoint, probe, kind), the
    label records they answer per kind (``raw_file`` ``<video>#<frame>~<kind>~<draw>``, ``frame`` added), the
    sheet's cells (the first checkpoint on the middle frame, draw 0) and, per vehicle kind, `hidden_counts` summed."""
    label_frames = [real_roads.video_frame(r) for r in records]
    depth = max(predictor.num_frames for _, predictor, _ in probes) - 1
    if min(label_frames) < depth:
        raise real_roads.RealRoadsError(f"labelled frame {min(label_frames)} has fewer than {depth} predecessors")
    images, fps = read_frames(video, {f - k for f in label_frames for k in range(depth + 1)})
    width = images[label_frames[0]].shape[1]
    sheet_frame = label_frames[len(label_frames) // 2]  # mid-clip: frame 121 of the ten
    preds: dict[tuple[str, str, str], list[dict]] = {(c, probe, k): [] for c, _, probe in probes for k in kinds}
    scored: dict[str, list[dict]] = {k: [] for k in kinds}
    sheet: dict[str, np.ndarray] = {}
    hidden: dict[str, list[int]] = {}
    for record, frame in zip(records, label_frames, strict=True):
        for kind in kinds:
            for draw in range(draws if kind != "none" else 1):
                seed = [frame, KINDS.index("vehicle" if kind in VEHICLE_KINDS else kind), draw]  # vehicle = traffic
                clean = [images[frame - k] for k in range(depth, -1, -1)]
                window = spoiled_window(clean, kind, seed, record, patches, fps)
                key = window[-1]
                if kind in VEHICLE_KINDS:
                    masks = window_covers(record, kind, seed, patches, fps, depth, key.shape[:2])
                    hidden[kind] = [a + b for a, b in zip(hidden.get(kind, [0, 0, 0]), hidden_counts(record, masks))]
                name = f"{record['raw_file']}~{kind}~{draw}"
                scored[kind].append(record | {"raw_file": name, "frame": frame})
                for ckpt, predictor, probe in probes:
                    history = window[len(window) - predictor.num_frames : -1]
                    lanes = run_probe(predictor, history if probe == "history" else [], key)
                    pred = real_roads.video_prediction(record, lanes, width)
                    preds[ckpt, probe, kind].append(pred | {"raw_file": name, "frame": frame})
                    if ckpt == probes[0][0] and frame == sheet_frame and draw == 0:
                        truth = [lane * (width / real_roads.TUSIMPLE_WIDTH) for lane in real_roads.gt_lanes(record)]
                        sheet[f"{kind}|{probe}"] = _cell(key, lanes, truth, f"{ckpt}, {probe}: {kind}")
    return preds, scored, sheet, hidden


def recipe_groups(names: list[str]) -> dict[str, list[str]]:
    """The checkpoints named ``<recipe>-s<seed>``, by recipe, where a recipe has two seeds or more."""
    groups: dict[str, list[str]] = {}
    for name in names:
        match = SEEDED.match(name)
        if match:
            groups.setdefault(match["recipe"], []).append(name)
    return {recipe: members for recipe, members in groups.items() if len(members) > 1}


def recipes(results: dict, frames: dict[str, list[int]], names: list[str], resamples: int) -> dict:
    """Per recipe (`recipe_groups`) and kind: the F1 of each probe and the history use over seeds (mean, std, each
    seed's), and the first recipe against each other one, seeds averaged per image, paired over frames."""
    groups = recipe_groups(names)
    first = next(iter(groups), None)
    out: dict[str, Any] = {}
    for recipe, members in groups.items():
        entry: dict[str, Any] = {"seeds": members, "kinds": {}}
        for kind, kind_frames in frames.items():
            row = {}
            for probe in ("history", "copies"):
                if (members[0], probe, kind) in results:
                    row[probe] = _over_seeds([results[m, probe, kind]["f1"] for m in members])
            if "copies" in row:
                row["history_use"] = _over_seeds(
                    [results[m, "history", kind]["f1"] - results[m, "copies", kind]["f1"] for m in members]
                )
            if first is not None and recipe != first:
                mine, theirs = (
                    {"rates": np.mean([results[m, "history", kind]["rates"] for m in group], axis=0)}
                    for group in (groups[first], members)
                )
                row[f"vs_{first}"] = paired(mine, theirs, kind_frames, resamples)
            entry["kinds"][kind] = row
        out[recipe] = entry
    return out


def _over_seeds(values: list[float]) -> dict:
    return {"mean": float(np.mean(values)), "std": float(np.std(values, ddof=1)), "per_seed": values}


def _cell(image: np.ndarray, lanes: list[np.ndarray], truth: list[np.ndarray], text: str) -> np.ndarray:
    from stamlane.predict.overlay import draw_lanes

    drawn = cv2.resize(draw_lanes(image, lanes, truth), SHEET_CELL, interpolation=cv2.INTER_AREA)
    for colour, thick in (((0, 0, 0), 4), ((255, 255, 255), 1)):
        cv2.putText(drawn, text, (8, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.6, colour, thick, cv2.LINE_AA)
    return drawn


def sheet_picture(cells: dict[str, np.ndarray], kinds: list[str]) -> np.ndarray | None:
    """A row per kind: the lanes with the real history, then with copies (the first checkpoint's)."""
    rows = []
    for kind in kinds:
        row = [cells[f"{kind}|{probe}"] for probe in ("history", "copies") if f"{kind}|{probe}" in cells]
        if row:
            rows.append(np.concatenate(row, axis=1))
    return np.concatenate(rows, axis=0) if rows else None


def _interval(value: float, low: float, high: float, sign: str = "") -> str:
    return f"{100 * value:{sign}.1f} [{100 * low:{sign}.1f}, {100 * high:{sign}.1f}]"


def _difference(diff: dict | None) -> str:
    return _interval(diff["diff"], diff["low"], diff["high"], "+") if diff else "–"


def _spread(value: dict | None, sign: str = "") -> str:
    return f"{100 * value['mean']:{sign}.1f} ± {100 * value['std']:.1f}" if value else "–"


def _table(head: list[str], rows: list[list[str]]) -> list[str]:
    return ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)] + ["| " + " | ".join(r) + " |" for r in rows]


def table(out: dict) -> str:
    """The numbers as markdown: per checkpoint, F1 per kind and probe with its interval, the history use and the
    first checkpoint against it; then, where checkpoints are seeds of recipes, the same over seeds (`recipes`)."""
    first = next(iter(out["checkpoints"]))
    rows = []
    for kind in out["kinds"]:
        for ckpt, entry in out["checkpoints"].items():
            history, copies = entry["kinds"][kind]["history"], entry["kinds"][kind].get("copies")
            rows.append(
                [
                    kind,
                    ckpt,
                    _interval(history["f1"], history["f1_low"], history["f1_high"]),
                    _interval(copies["f1"], copies["f1_low"], copies["f1_high"]) if copies else "–",
                    _difference(copies["history_use"] if copies else None),
                    _difference(history.get(f"vs_{first}")),
                ]
            )
    head = ["key frame", "checkpoint", "F1, real history", "F1, copies", "history use", f"{first} − it"]
    lines = _table(head, rows)
    if out.get("recipes"):
        lines += ["", *recipe_table(out)]
    if out.get("hidden_points"):
        counts = [
            [kind, str(c["points"]), f"{100 * c['hidden'] / max(c['points'], 1):.1f}",
             f"{100 * c['free_in_history'] / max(c['hidden'], 1):.1f}"]
            for kind, c in out["hidden_points"].items()
        ]  # fmt: skip
        head = ["key frame", "labelled points", "% hidden by the vehicles", "% of those free in an earlier frame"]
        lines += ["", *_table(head, counts)]
    return "\n".join(lines) + "\n"


def recipe_table(out: dict) -> list[str]:
    """The recipes over seeds: mean ± std per probe and of the history use; the first recipe against each, paired."""
    first = next(iter(out["recipes"]))
    rows = []
    for kind in out["kinds"]:
        for recipe, entry in out["recipes"].items():
            row = entry["kinds"][kind]
            rows.append(
                [
                    kind,
                    recipe,
                    str(len(entry["seeds"])),
                    _spread(row["history"]),
                    _spread(row.get("copies")),
                    _spread(row.get("history_use"), "+"),
                    _difference(row.get(f"vs_{first}")),
                ]
            )
    head = ["key frame", "recipe", "seeds", "F1, real history", "F1, copies", "history use", f"{first} − it"]
    return _table(head, rows)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--ckpt", nargs="+", default=list(DEFAULT_CKPTS), help="shipped model names or checkpoints")
    parser.add_argument(
        "--kinds", nargs="+", default=list(DEFAULT_KINDS), help=f"key-frame spoils, of {' '.join(KINDS)}"
    )
    parser.add_argument("--draws", type=int, default=DEFAULT_DRAWS, help=f"spoils per frame and kind (1-{MAX_DRAWS})")
    parser.add_argument("--frames", type=int, help="only the first N labelled frames")
    parser.add_argument("--resamples", type=int, default=2000, help=f"bootstrap resamples (100-{MAX_RESAMPLES})")
    parser.add_argument("--shared", type=Path, default=real_roads.REPO.parent / "shared", help="the folder of data/")
    parser.add_argument("--out", type=Path, default=Path("outputs/bench/real-history"))
    args = parser.parse_args(argv)
    from stamlane.safety.guard import GuardError, check_outputs, write_atomic
    from stamlane.training.quiet import quiet_libraries

    quiet_libraries()
    ranges = {"draws": Within(1, MAX_DRAWS), "resamples": Within(100, MAX_RESAMPLES), "frames": Within(1)}
    problem = option_problem(vars(args), choices={"kinds": KINDS}, ranges=ranges)
    video = args.shared / real_roads.VIDEO
    if problem is None and not video.is_file():
        problem = f"{video} does not exist (the real video lives in ../shared beside the project)"
    if problem is None:
        inputs = [real_roads.VIDEO_LABELS, *(Path(c) for c in args.ckpt if Path(c).exists())]
        try:  # before any model runs: --out may be neither a file nor inside the data or an input
            check_outputs(reads=inputs, folders=[args.out], protected=[args.shared, *inputs])
        except GuardError as err:
            problem = str(err)
    if problem is not None:
        return fail("real_history", problem)
    kinds = list(dict.fromkeys(args.kinds))
    try:
        patches = read_patches(args.shared) if set(kinds) & set(VEHICLE_KINDS) else []
        out, cells = run(args.ckpt, video, kinds, args.draws, args.resamples, args.frames, patches)
    except real_roads.RealRoadsError as err:
        return fail("real_history", err)
    write_result(args.out / "real-history.json", out, quiet=True)
    summary = table(out)
    write_atomic(args.out / "summary.md", summary)
    picture = sheet_picture(cells, out["kinds"])
    if picture is not None:
        write_image(args.out / "sheet.jpg", picture, [cv2.IMWRITE_JPEG_QUALITY, real_roads.STRIP_QUALITY])
    print(summary, end="")
    print(f"wrote {args.out}/: real-history.json, summary.md" + (", sheet.jpg" if picture is not None else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
