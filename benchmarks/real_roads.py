"""The real-road check: how a checkpoint does on real labelled frames and on a real highway video.

    python benchmarks/real_roads.py [--ckpt NAME_OR_FILE ...] [--shared ../shared] [--split dev|sealed] [--frames N]
                                    [--video-frames N] [--strip 4] [--out outputs/bench/real-roads]
                                    [--decode NAME:KEY=VALUE,... ...] [--val SYNTHETIC_ROOT [--val-labels val.json]]

Runs every ``--ckpt`` (default: every shipped model, `stamlane.weights.SHIPPED`) through `StreamingPredictor`,
loaded as ``stamlane stream --ckpt`` loads it (`stamlane.training.stored.StoredModel`, on the CPU, the model's own
precision, alignment on), on the real data beside the project (``../shared``, never committed):

1. **Labelled frames**: the six 1280x720 highway frames of ``data/frames/`` with their TuSimple labels
   ``data/lanenet_frames.json`` (from the instance masks that come with them). Each frame is its own clip (the
   predictor is reset before it, so the frame is its own history, as ``stamlane predict`` starts a sequence),
   its lanes sampled at the label's ``h_samples`` and scored by lane.py's rules (`stamlane_eval.tusimple.evaluate`,
   no time limit: this shared CPU is no benchmark machine): F1, accuracy, FP, FN, per image too; and its ceiling,
   the F1 of the labels themselves cut at the model's ``crop_top`` (`crop_ceiling`: a lane labelled far above the
   crop cannot be matched, whatever the network draws).
2. **Video**: ``data/real/solidWhiteRight.mp4`` (960x540, 221 frames, a California highway whose painted lines do
   not change), streamed frame by frame with history. Per frame, the lanes found; over the video, the histogram of
   lanes per frame, the frames with more than `MAX_LANES` lanes, the lane-count changes from one frame to the
   next, and the lateral jitter of the lanes matched between consecutive frames (`stability`); lane pairs that
   cross each other (`crossings`: two lanes of one frame whose left-right order changes from row to row). And
   lane.py's numbers on the video's labelled frames (`VIDEO_LABELS`, ten frames labelled by a written rule,
   ``benchmarks/video_labels.py``; `score_video_frames`): the one real-road F1 where a 4-frame model sees real
   history.
3. **Overlay strip** ``<name>-strip.jpg``: a few video frames with their lanes (top row) and the first labelled
   frames with their labels (yellow bands) under the predictions (bottom row), for a person to look at: what no
   number here says is whether a lane runs through a vehicle.

4. **Decoding alternatives** (``--decode``): each ``NAME:KEY=VALUE,...`` decodes the same network outputs with the
   model's `PostprocessConfig` changed as it says (``model``: the model's own), e.g. ``no-extend:extend=false``;
   every number above is given per decoding. ``--val ROOT`` also scores each decoding on a SYNTHETIC validation
   split (``ROOT/val.json``, each clip streamed from its first frame, its labelled key frames scored by lane.py):
   where a decoding is to be chosen; the real frames only report what the choice does.

Every set of labelled frames is also scored by lane position (ego pair, adjacent, outer: recall) and by the lines'
count against the labels', F1 and both with 95 % bootstrap intervals over frames (`real_frames`).
``--split sealed`` scores the sealed video frames instead (docs/real-protocol.md: once per release, each model's own
decoding; ``<name>-sealed.json``, ``summary-sealed.md``); the default, dev, never reads their labels.

Writes ``<out>/<name>.json`` and ``<out>/<name>-strip.jpg`` per checkpoint (each atomically; ``<name>@<decoding>``
with ``--decode``) and prints a table;
``<out>/summary.md`` holds the table of every checkpoint of the run. Exit status 2 with one line where
``--shared`` lacks the data, a label file is bad (no JSON lines, a frame twice, a ``raw_file`` leading out of its
folder) or a checkpoint cannot be read.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections import Counter
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import real_frames  # a benchmark module beside this one: label files, the split, the numbers by lane position
from _harness import Within, fail, option_problem, write_image, write_result
from real_roads_tables import dev_lanes_rows, lanes_table, sealed_table, table
from real_video_stats import crossings, stability

REPO = Path(__file__).resolve().parents[1]
FRAMES_LABELS = "data/lanenet_frames.json"  # under --shared; raw_file is relative to data/
VIDEO = "data/real/solidWhiteRight.mp4"
VIDEO_LABELS = REPO / "benchmarks" / "labels" / "solidWhiteRight.json"  # TuSimple records, 1280 x 720 pixels (dev)
SEALED_LABELS = REPO / "benchmarks" / "labels" / "solidWhiteRight-sealed.json"  # the sealed frames (real-protocol.md)
TUSIMPLE_WIDTH, TUSIMPLE_HEIGHT = 1280, 720  # the labels' frame: the video's lanes are scaled to it before scoring
MAX_LANES = 4  # the bound: a highway frame shows at most four lines worth drawing
STABILITY_ROW_STEP = 10  # px between the rows lanes are compared on
STRIP_CELL = (480, 270)  # W, H of a frame in the overlay strip
STRIP_QUALITY = 80  # JPEG quality of the strip (~200 KB for two rows of four)


class RealRoadsError(Exception):
    """Missing data or an unreadable checkpoint (one line, exit status 2)."""


# ------------------------------------------------------------------------------------------- predictor
def load(ckpt: str) -> Any:
    """A `StreamingPredictor` for ``ckpt`` (a shipped model's name, a checkpoint file or a run folder) with every
    setting the model was trained with, on the CPU (`stamlane.training.stored.StoredModel`, as ``stamlane stream``)."""
    from stamlane.safety.checkpoints import CheckpointError
    from stamlane.stream.predictor import StreamingPredictor
    from stamlane.training.stored import StoredModel

    try:
        return StreamingPredictor.from_stored(StoredModel.open(ckpt))
    except CheckpointError as err:
        raise RealRoadsError(str(err)) from None


# ------------------------------------------------------------------------------------------- the frames
def read_labels(shared: Path, limit: int | None = None) -> tuple[list[dict], Path]:
    """The TuSimple records of the labelled frames (``limit`` first ones) and the folder their ``raw_file`` is in."""
    path = shared / FRAMES_LABELS
    if not path.is_file():
        raise RealRoadsError(f"{path} does not exist (the real labelled frames live in ../shared beside the project)")
    records = real_frames.read_label_file(path)
    for record in records:  # a raw_file with .. or a link out of the folder is never read
        real_frames.frame_file(path.parent, record["raw_file"], path)
    return records[:limit] if limit else records, path.parent


def decodings(predictor: Any, specs: list[str] | None) -> dict[str, Any]:
    """The `PostprocessConfig` of each ``--decode`` spec (``NAME:KEY=VALUE,...``; ``model`` alone: the model's own),
    by name; the model's own when there is none."""
    import dataclasses

    base = predictor.postprocess
    fields = {f.name: f for f in dataclasses.fields(base)}
    out = {}
    for spec in specs or ["model"]:
        name, _, body = spec.partition(":")
        if not name or name in out or "@" in name or "/" in name:
            raise RealRoadsError(f"--decode {spec!r}: give each decoding its own plain name, NAME:KEY=VALUE,...")
        changes: dict[str, Any] = {}
        for item in filter(None, body.split(",")):
            key, eq, value = item.partition("=")
            if not eq or key not in fields:
                raise RealRoadsError(f"--decode {spec!r}: {item!r} is not KEY=VALUE of {sorted(fields)}")
            old = getattr(base, key)
            try:
                if value.lower() in ("none", "null"):
                    changes[key] = None
                elif isinstance(old, bool):
                    changes[key] = {"true": True, "false": False}[value.lower()]
                else:
                    changes[key] = type(old)(value) if old is not None else float(value)
            except (KeyError, ValueError):
                raise RealRoadsError(f"--decode {spec!r}: {value!r} is no value of {key}") from None
        try:
            out[name] = dataclasses.replace(base, **changes)
        except ValueError as err:
            raise RealRoadsError(f"--decode {spec!r}: {err}") from None
    return out


def lanes_of(predictor: Any, image: np.ndarray, configs: dict[str, Any], rows: list | None) -> dict[str, list]:
    """The next frame through the network once, its lanes decoded by each of ``configs`` (at ``rows``, if given)."""
    from stamlane.predict.postprocess import decode_lanes

    out = predictor(image)
    prob = out.logits.softmax(dim=1)[0, 1].numpy()
    embedding = out.embedding[0].numpy()
    orig_from_net = np.linalg.inv(out.net_from_orig)
    return {
        name: decode_lanes(prob, embedding, orig_from_net, config, y_samples=rows, orig_size=image.shape[:2])
        for name, config in configs.items()
    }


def _scores(
    preds: list[dict], records: list[dict], found: list[int] | None = None, sizes: list[tuple[int, int]] | None = None
) -> dict:
    """lane.py's numbers of ``preds`` on ``records``, per image too; with the lines each decoding drew (``found``)
    and the labels' frame sizes (``sizes``, W x H), F1's interval over frames and the numbers by lane position and
    count (`real_frames.lane_numbers`)."""
    from stamlane_eval.tusimple import evaluate

    result = evaluate(preds, records, time_limit=False)
    per_image = [
        {"raw_file": r["raw_file"], "acc": i.acc, "fp": i.fp, "fn": i.fn, "pred_lanes": i.n_pred, "gt_lanes": i.n_gt}
        for r, i in zip(records, result.per_image, strict=True)
    ]
    numbers = {k: result.as_dict()[k] for k in ("f1", "accuracy", "fp", "fn", "images", "lane_tp", "lane_fp")}
    if found is not None and sizes is not None:
        lanes = real_frames.lane_numbers(preds, found, records, sizes)
        numbers |= {"f1_interval": real_frames.f1_interval(per_image)} | lanes
    return numbers | {"per_image": per_image}


def crop_ceiling(records: list[dict], heights: list[int], crop_top: float) -> dict:
    """What a model that sees only the rows below its crop can score at most on ``records``: lane.py's numbers of the
    labels themselves, every point above row ``crop_top * height`` of its frame removed, the lanes that can no longer
    be matched left out (drawing them would only add false positives).

    lane.py matches a lane when `POINT_THRESH` of the h_samples rows agree, and counts a row the label draws but the
    prediction leaves empty as a miss: a lane labelled far above the crop (a horizon higher in the frame than in the
    training clips, an uphill road) is out of reach whatever the network does."""
    from stamlane_eval.tusimple import POINT_THRESH, evaluate

    reachable, out_of_reach = [], 0
    for record, height in zip(records, heights, strict=True):
        top, rows, keep = crop_top * height, record["h_samples"], []
        for xs in filter(lambda xs: max(xs) >= 0, record["lanes"]):
            cut = [x if y >= top else -2 for x, y in zip(xs, rows, strict=True)]
            lost = sum(x >= 0 > c for x, c in zip(xs, cut, strict=True))  # rows drawn by the label, lost to the crop
            if 1 - lost / len(rows) >= POINT_THRESH:
                keep.append(cut)
            else:
                out_of_reach += 1
        reachable.append({"raw_file": record["raw_file"], "lanes": keep, "run_time": 0})
    f1 = evaluate(reachable, records, time_limit=False).f1
    return {"crop_top": crop_top, "f1": f1, "lanes_out_of_reach": out_of_reach}


def score_frames(
    predictor: Any, records: list[dict], root: Path, configs: dict[str, Any]
) -> dict[str, tuple[dict, list[list[np.ndarray]]]]:
    """Per decoding: lane.py's numbers of the predictor on the labelled frames, each frame its own clip, with the
    `crop_ceiling` of its crop; and the lanes found."""
    from stamlane_eval.tusimple import lanes_to_xs

    preds: dict[str, list] = {name: [] for name in configs}
    found: dict[str, list] = {name: [] for name in configs}
    heights, sizes = [], []
    for record in records:
        image = cv2.imread(str(root / record["raw_file"]))
        if image is None:
            raise RealRoadsError(f"cannot read {root / record['raw_file']}")
        heights.append(image.shape[0])
        sizes.append((image.shape[1], image.shape[0]))
        predictor.reset()
        start = time.perf_counter()
        lanes = lanes_of(predictor, image, configs, list(record["h_samples"]))
        ms = (time.perf_counter() - start) * 1e3
        for name, these in lanes.items():
            found[name].append(these)
            xs = lanes_to_xs(these, record["h_samples"])
            preds[name].append({"raw_file": record["raw_file"], "lanes": xs, "run_time": ms})
    ceiling = crop_ceiling(records, heights, predictor.transform.crop_top)
    return {
        name: (
            _scores(preds[name], records, [len(f) for f in found[name]], sizes) | {"crop_ceiling": ceiling},
            found[name],
        )
        for name in configs
    }


def score_synthetic(predictor: Any, root: Path, labels: str, configs: dict[str, Any]) -> dict[str, dict]:
    """Per decoding: lane.py's numbers on a synthetic split's labelled key frames (``root/labels``), each clip streamed
    through the predictor from its first frame (the key frames' history is the clip's own)."""
    from stamlane_eval.tusimple import lanes_to_xs

    path = root / labels
    if not path.is_file():
        raise RealRoadsError(f"{path} does not exist (give --val a synthetic set: stamlane synth --out ROOT ...)")
    records = real_frames.read_label_file(path)
    by_clip: dict[str, dict[int, dict]] = {}
    for record in records:
        raw = real_frames.frame_file(root, record["raw_file"], path).relative_to(root)
        if not raw.stem.isdigit() or not raw.stem.isascii():
            raise RealRoadsError(f"{path}: raw_file {record['raw_file'][:80]!r} is no clip frame (<clip>/<n>.jpg)")
        by_clip.setdefault(str(raw.parent), {})[int(raw.stem)] = record
    preds: dict[str, dict[str, dict]] = {name: {} for name in configs}
    for clip, keys in by_clip.items():
        predictor.reset()
        for index in range(1, max(keys) + 1):
            image = cv2.imread(str(root / clip / f"{index}.jpg"))
            if image is None:
                raise RealRoadsError(f"cannot read {root / clip / f'{index}.jpg'}")
            record = keys.get(index)
            lanes = lanes_of(predictor, image, configs, list(record["h_samples"]) if record else None)
            if record is not None:
                for name, these in lanes.items():
                    xs = lanes_to_xs(these, record["h_samples"])
                    preds[name][record["raw_file"]] = {"raw_file": record["raw_file"], "lanes": xs, "run_time": 0.0}
    out = {}
    for name in configs:
        numbers = _scores([preds[name][r["raw_file"]] for r in records], records)
        out[name] = {k: v for k, v in numbers.items() if k != "per_image"} | {"labels": str(path)}
    return out


# -------------------------------------------------------------------------------------------- the video
def run_video(
    predictor: Any, path: Path, max_frames: int | None, configs: dict[str, Any]
) -> tuple[dict[str, tuple[dict, list[list]]], list[np.ndarray]]:
    """Stream the video through the predictor; per decoding its numbers and the frames' lanes; the frames."""
    from stamlane.stream.cli import StreamError, iter_frames

    try:
        frames, _, _ = iter_frames(path, max_frames)
        predictor.reset()
        images, ms = [], []
        found: dict[str, list] = {name: [] for name in configs}
        for _, image in frames:
            start = time.perf_counter()
            for name, lanes in lanes_of(predictor, image, configs, None).items():
                found[name].append(lanes)
            ms.append((time.perf_counter() - start) * 1e3)
            images.append(image)
    except StreamError as err:
        raise RealRoadsError(str(err)) from None
    return {name: (video_numbers(path, images, lanes, ms), lanes) for name, lanes in found.items()}, images


def video_numbers(path: Path, images: list[np.ndarray], found: list[list], ms: list[float]) -> dict:
    """The numbers of the lanes ``found`` in the video's frames."""
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
    return numbers | {"lanes_per_frame_sequence": counts}


def read_video_labels(path: Path = VIDEO_LABELS) -> list[dict]:
    """The TuSimple records of the video's labelled frames (``raw_file`` ``<video>#<frame>``): the dev ones, or
    those of ``path`` (`SEALED_LABELS`); checked as a ground truth, each naming a frame of the video once."""
    records = real_frames.read_label_file(path)
    for record in records:
        real_frames.video_index(record["raw_file"], Path(VIDEO).name, path)
    return records


def score_video_frames(
    found: list[list[np.ndarray]], records: list[dict], width: int, labels: Path = VIDEO_LABELS
) -> dict | None:
    """lane.py's numbers of the lanes ``found`` in the video's frames on its labelled ones (``records``, in TuSimple's
    1280 x 720: the lanes are scaled by ``TUSIMPLE_WIDTH / width`` first, so that lane.py's 20-px threshold means what
    it means on TuSimple), with the numbers by lane position and count; None where the frames streamed end before
    the first labelled one."""
    scored = [r for r in records if video_frame(r) < len(found)]
    if not scored:
        return None
    preds = [video_prediction(record, found[video_frame(record)], width) for record in scored]
    counts = [len(found[video_frame(record)]) for record in scored]
    sizes = [(TUSIMPLE_WIDTH, TUSIMPLE_HEIGHT)] * len(scored)
    shown = labels.relative_to(REPO) if labels.is_relative_to(REPO) else labels
    return _scores(preds, scored, counts, sizes) | {"labels": str(shown)}


def video_frame(record: dict) -> int:
    """The frame index of a labelled video frame (``raw_file`` ``<video>#<frame>``)."""
    return int(record["raw_file"].rpartition("#")[2])


def video_prediction(record: dict, lanes: list[np.ndarray], width: int) -> dict:
    """The lane.py prediction record of ``lanes`` (pixels of a frame ``width`` wide) for the labelled ``record``:
    scaled to TuSimple's 1280 x 720 and sampled at its rows."""
    from stamlane_eval.tusimple import lanes_to_xs

    scaled = [lane * (TUSIMPLE_WIDTH / width) for lane in lanes]
    return {"raw_file": record["raw_file"], "lanes": lanes_to_xs(scaled, record["h_samples"]), "run_time": 0}


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


def gt_lanes(record: dict) -> list[np.ndarray]:
    """The labelled lanes of a TuSimple ``record`` as ``(N, 2)`` point arrays, lanes absent on every row left out."""
    from stamlane_eval.io import tusimple_points

    return [lane for lane in tusimple_points(record["lanes"], record["h_samples"]) if len(lane)]


# ----------------------------------------------------------------------------------------------- report
def check(
    ckpt: str,
    shared: Path,
    frames: int | None,
    video_frames: int | None,
    cells: int,
    specs: list[str] | None = None,
    val: tuple[Path, str] | None = None,
) -> list[tuple[str, dict, np.ndarray]]:
    """Every number of the real-road check for one checkpoint on the dev frames, per decoding (``specs``,
    `decodings`): its name (``<checkpoint>``, or ``<checkpoint>@<decoding>`` with ``specs``), numbers and overlay
    strip; with ``val`` (a synthetic root and its label file) the synthetic validation numbers too."""
    import dataclasses

    records, root = read_labels(shared, frames)
    video = shared / VIDEO
    if not video.is_file():
        raise RealRoadsError(f"{video} does not exist (the real video lives in ../shared beside the project)")
    video_records = dev_video_labels()
    predictor = load(ckpt)
    configs = decodings(predictor, specs)
    synthetic = score_synthetic(predictor, val[0], val[1], configs) if val is not None else {}
    labelled_numbers = score_frames(predictor, records, root, configs)
    video_results, images = run_video(predictor, video, video_frames, configs)
    labelled = [cv2.imread(str(root / r["raw_file"])) for r in records[:cells]]
    gt = [gt_lanes(r) for r in records[:cells]]
    out = []
    for name, config in configs.items():
        full = f"{Path(ckpt).stem}@{name}" if specs else Path(ckpt).stem
        frame_numbers, frame_lanes = labelled_numbers[name]
        video_numbers, video_lanes = video_results[name]
        video_labelled = score_video_frames(video_lanes, video_records, images[0].shape[1])
        if video_labelled is not None:
            video_numbers = video_numbers | {"labelled_frames": video_labelled}
        picture = strip(images, video_lanes, labelled, frame_lanes[:cells], gt, cells, full)
        result = {
            "split": "dev",
            "checkpoint": ckpt,
            "num_frames": predictor.num_frames,
            "image_size": list(predictor.image_size),
            "crop_top": predictor.transform.crop_top,
            "decoding": name if specs else "model",
            "postprocess": dataclasses.asdict(config),
            "labelled_frames": frame_numbers,
            "video": video_numbers,
        }
        if name in synthetic:
            result["synthetic_val"] = synthetic[name]
        out.append((full, result, picture))
    return out


def dev_video_labels() -> list[dict]:
    """The video's dev labels, refused where one names a sealed frame (`real_frames.read_split`)."""
    records = read_video_labels()
    sealed = set(real_frames.read_split()["sealed"])
    leak = [r["raw_file"] for r in records if r["raw_file"] in sealed]
    if leak:
        raise RealRoadsError(f"{VIDEO_LABELS}: {leak[0]!r} is a sealed frame (docs/real-protocol.md)")
    return records


def sealed_labels() -> list[dict]:
    """The sealed frames' labels, refused unless they are the ones the split was made from (its SHA-256) and every
    one is a sealed frame."""
    records = read_video_labels(SEALED_LABELS)
    key = str(SEALED_LABELS.relative_to(REPO))
    real_frames.check_split_labels(real_frames.read_split(), key, SEALED_LABELS, records, "sealed")
    return records


def check_sealed(ckpt: str, shared: Path, video_frames: int | None, cells: int) -> tuple[str, dict, np.ndarray]:
    """The sealed frames' numbers of one checkpoint, its own decoding (docs/real-protocol.md: scored once per
    release): the video streamed with history, lane.py's numbers on the sealed frames with their interval, by lane
    position and count, per stretch of the video; and a strip of the first sealed frames (labels as yellow bands
    under the predictions)."""
    from stamlane_eval.tusimple import evaluate

    records = sealed_labels()
    video = shared / VIDEO
    if not video.is_file():
        raise RealRoadsError(f"{video} does not exist (the real video lives in ../shared beside the project)")
    predictor = load(ckpt)
    configs = decodings(predictor, None)
    streamed, images = run_video(predictor, video, video_frames, configs)
    lanes = streamed["model"][1]
    width = images[0].shape[1]
    numbers = score_video_frames(lanes, records, width, SEALED_LABELS)
    if numbers is None:
        raise RealRoadsError(f"--video-frames {video_frames} ends before the first sealed frame")
    scored = [r for r in records if video_frame(r) < len(lanes)]
    by_stretch: dict[str, list[dict]] = {}
    for record in scored:
        by_stretch.setdefault(real_frames.stretch_of(video_frame(record)), []).append(record)
    stretches = {}
    for stretch, these in by_stretch.items():
        result = evaluate([video_prediction(r, lanes[video_frame(r)], width) for r in these], these, time_limit=False)
        stretches[stretch] = {"f1": result.f1, "images": result.images}
    picks = scored[:cells]
    scale = width / TUSIMPLE_WIDTH
    gt = [[lane * scale for lane in gt_lanes(r)] for r in picks]
    picked = [images[video_frame(r)] for r in picks]
    title = f"{Path(ckpt).stem} sealed"
    picture = strip(images, lanes, picked, [lanes[video_frame(r)] for r in picks], gt, cells, title)
    result = {
        "split": "sealed",
        "protocol": "docs/real-protocol.md",
        "checkpoint": ckpt,
        "num_frames": predictor.num_frames,
        "image_size": list(predictor.image_size),
        "crop_top": predictor.transform.crop_top,
        "video": {"video": video.name, "frames": len(lanes), "labelled_frames": numbers, "by_stretch": stretches},
    }
    return f"{Path(ckpt).stem}-sealed", result, picture


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--ckpt", nargs="+", help="shipped model names or checkpoint files (default: every shipped)")
    parser.add_argument("--shared", type=Path, default=REPO.parent / "shared", help="the folder holding data/")
    parser.add_argument(
        "--split",
        choices=real_frames.SPLITS,
        default="dev",
        help="dev (default): the photos and the video's dev frames; sealed: the sealed frames, once per release",
    )
    parser.add_argument("--frames", type=int, help="score only the first N labelled frames")
    parser.add_argument("--video-frames", type=int, help="stream only the first N video frames")
    parser.add_argument("--strip", type=int, default=4, help="frames per row of the overlay strip")
    parser.add_argument("--out", type=Path, default=Path("outputs/bench/real-roads"))
    parser.add_argument(
        "--decode",
        nargs="+",
        metavar="NAME:KEY=VALUE,...",
        help="decode the same network outputs several ways (e.g. model no-extend:extend=false curve:degree=2)",
    )
    parser.add_argument("--val", type=Path, help="a synthetic set whose validation split scores each decoding too")
    parser.add_argument("--val-labels", default="val.json", help="its label file (default val.json)")
    args = parser.parse_args(argv)
    from stamlane.safety.guard import GuardError, check_outputs, write_atomic
    from stamlane.training.quiet import quiet_libraries
    from stamlane.weights import SHIPPED

    quiet_libraries()
    if problem := option_problem(vars(args), ranges=dict.fromkeys(("frames", "video_frames", "strip"), Within(1))):
        return fail("real_roads", problem)
    sealed = args.split == "sealed"
    ckpts = args.ckpt or [m.name for m in SHIPPED]
    results, pictures = [], []
    try:
        if sealed and (args.frames or args.decode or args.val):
            raise RealRoadsError(
                "--split sealed scores the sealed frames with each model's own decoding only: "
                "give no --frames, --decode or --val (docs/real-protocol.md)"
            )
        sealed_labels() if sealed else (read_labels(args.shared), dev_video_labels())  # the data before any model
        try:  # --out may be neither a file nor inside the data beside the project
            check_outputs(folders=[args.out], protected=[args.shared])
        except GuardError as err:
            raise RealRoadsError(str(err)) from None
        if not (args.shared / VIDEO).is_file():
            raise RealRoadsError(f"{args.shared / VIDEO} does not exist (the real video lives in ../shared)")
        from stamlane.predict.postprocess import PostprocessConfig

        decodings(argparse.Namespace(postprocess=PostprocessConfig()), args.decode)  # a bad spec before any model
        val = (args.val, args.val_labels) if args.val is not None else None
        if val is not None and not (args.val / args.val_labels).is_file():
            raise RealRoadsError(f"{args.val / args.val_labels} does not exist (--val takes a synthetic set)")
        for record in real_frames.read_label_file(args.val / args.val_labels) if val is not None else []:
            real_frames.frame_file(args.val, record["raw_file"], args.val / args.val_labels)  # before any model
        for ckpt in ckpts:
            print(f"real_roads: {ckpt} ({args.split}) ...", file=sys.stderr)
            if sealed:
                checked = [check_sealed(ckpt, args.shared, args.video_frames, args.strip)]
            else:
                checked = check(ckpt, args.shared, args.frames, args.video_frames, args.strip, args.decode, val)
            for name, result, picture in checked:
                results.append(result)
                pictures.append((name, picture))
    except (RealRoadsError, real_frames.RealFramesError) as err:
        return fail("real_roads", err)
    for result, (name, picture) in zip(results, pictures, strict=True):
        write_image(args.out / f"{name}-strip.jpg", picture, [cv2.IMWRITE_JPEG_QUALITY, STRIP_QUALITY])
        write_result(args.out / f"{name}.json", result, quiet=True)
    if sealed:
        summary = "Sealed frames (docs/real-protocol.md), each model's own decoding:\n\n" + sealed_table(results)
    else:
        summary = table(results) + "\nBy lane position and count (dev):\n\n" + lanes_table(dev_lanes_rows(results))
    summary_name = "summary-sealed.md" if sealed else "summary.md"
    write_atomic(args.out / summary_name, summary)
    print(summary, end="")
    print(f"wrote {args.out}/: " + ", ".join(f"{n}.json, {n}-strip.jpg" for n, _ in pictures) + f", {summary_name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
