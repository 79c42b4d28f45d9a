"""Where the lines beyond the ego pair go missing: in the network's lane probability map, or in the decoding.

    python benchmarks/outer_lanes.py [--ckpt NAME_OR_FILE ...] [--shared ../shared] [--out DIR] [--pictures DIR]
                                     [--columns 4]

Runs every ``--ckpt`` (default: `stam4-dashcam` and `single-dashcam`) as ``stamlane stream`` loads it
(`real_roads.load`) on the six DEV photos (docs/real-protocol.md: ``../shared/data/frames`` with
``lanenet_frames.json``; the sealed labels are never read), each photo its own clip, and places every labelled line
(`real_frames.positions`: ego, adjacent, outer) and says what became of it (`real_frames.CAUSES`):

- **matched**: lane.py matches it (`real_frames.matched_lanes`);
- **absent**: the lane probability map does not hold it: fewer than `real_frames.PRESENT_ROWS` of its labelled rows
  inside the network's view have a pixel above the decoding's ``prob_thresh`` within ``--columns`` network columns
  (`real_frames.line_support`). No decoding setting above that threshold can draw it;
- **not clustered**: the map holds it, but most of its lane pixels end up in no drawn lane (unassigned by DBSCAN's
  nearest-centre step, or in a cluster below ``min_cluster_pixels``): the decoding dropped it;
- **merged**: most of its lane pixels are in a drawn lane that holds most of another labelled line's too;
- **drawn off the label**: a drawn lane of its own follows it, and lane.py still does not match it (fewer than 85 %
  of its rows within 20 px: the fit, the extension or the network's line beside the paint).

The decoding is the model's own (`PostprocessConfig`), taken apart as `stamlane.predict.postprocess.decode_lanes`
does it (lane pixels, DBSCAN on the confident ones, nearest centre, the clusters' sizes, a curve per cluster).

Writes ``<out>/outer-lanes.json`` (per checkpoint, photo and line: position, support, owner, cause; the causes
counted by position) and prints the table; with ``--pictures DIR`` one PNG per photo: the network's view with the
labels (yellow) and the drawn lanes (red), and under it each checkpoint's lane probability map with the same lines.
Exit status 2 with one line where the data or a checkpoint is missing.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import real_frames
from _harness import fail, write_image, write_result
from real_roads import RealRoadsError, load, read_labels

REPO = Path(__file__).resolve().parents[1]
DEFAULT_CKPTS = ("stam4-dashcam", "single-dashcam")
PICTURE_SCALE = 2  # network pixels per picture pixel side: 80x256 -> 160x512 a panel
OWNED = 0.5  # share of a line's lane pixels a drawn cluster must hold for the line to be in it


def decode_parts(prob: np.ndarray, embedding: np.ndarray, orig_from_net: np.ndarray, config: Any) -> dict[str, Any]:
    """`decode_lanes`' steps for one image: the lane pixels ``(ys, xs)``, their cluster labels and which clusters are
    drawn (`fit_curve` gives a curve, the cluster is at least ``min_pixels`` and among the first ``max_lanes``)."""
    from stamlane.predict.postprocess import cluster_lane_pixels, fit_curve

    ys, xs = np.nonzero(prob > config.prob_thresh)
    scale = config.pixel_scale((prob.shape[0], prob.shape[1]))
    confident = None
    if config.cluster_thresh is not None and config.cluster_thresh > config.prob_thresh and len(ys):
        confident = prob[ys, xs] > config.cluster_thresh
        if int(confident.sum()) < config.core_samples(int(confident.sum()), scale):
            confident = None
    labels = cluster_lane_pixels(embedding[:, ys, xs].T, config, confident, scale) if len(ys) else np.zeros(0, int)
    counts = np.bincount(labels[labels >= 0], minlength=1)
    homogeneous = np.stack([xs, ys, np.ones_like(xs)]).astype(np.float64)
    mapped = orig_from_net @ homogeneous
    orig = (mapped[:2] / np.where(mapped[2:] == 0, 1e-12, mapped[2:])).T
    drawn: list[int] = []
    for cluster in range(len(counts)):
        if counts[cluster] < config.min_pixels(scale) or len(drawn) >= config.max_lanes:
            continue
        if fit_curve(orig[labels == cluster], config) is not None:
            drawn.append(cluster)
    return {"ys": ys, "xs": xs, "labels": labels, "drawn": drawn, "sizes": counts.tolist()}


def line_clusters(parts: dict[str, Any], net_points: np.ndarray, columns: int) -> list[int]:
    """The cluster labels (-1: noise) of the lane pixels within ``columns`` network columns of a labelled line's
    points, on their rows."""
    out: list[int] = []
    for x, y in np.asarray(net_points).reshape(-1, 2):
        near = (parts["ys"] == int(np.floor(y))) & (np.abs(parts["xs"] - x) <= columns)
        out.extend(int(v) for v in parts["labels"][near])
    return out


def owners(members: list[list[int]], drawn: list[int]) -> list[str]:
    """Per labelled line (its pixels' cluster labels), ``noise``, ``shared`` or ``own`` (`real_frames.miss_cause`)."""
    main: list[int | None] = []
    for labels in members:
        in_drawn = Counter(v for v in labels if v in drawn)
        top = in_drawn.most_common(1)
        main.append(top[0][0] if top and top[0][1] >= OWNED * max(len(labels), 1) else None)
    return ["noise" if c is None else ("shared" if sum(m == c for m in main) > 1 else "own") for c in main]


def analyse(predictor: Any, image: np.ndarray, record: dict, columns: int) -> tuple[dict[str, Any], dict[str, Any]]:
    """One photo through one predictor: per labelled line its position, support, owner and cause; and what its
    picture needs (the network's view, the lane map, labels and drawn lanes in network pixels)."""
    from stamlane_eval.tusimple import lanes_to_xs

    from stamlane.predict.postprocess import decode_lanes

    config = predictor.postprocess
    predictor.reset()
    out = predictor(image)
    prob = out.logits.float().softmax(dim=1)[0, 1].numpy()
    embedding = out.embedding[0].float().numpy()
    net_from_orig = np.asarray(out.net_from_orig, dtype=np.float64)
    orig_from_net = np.linalg.inv(net_from_orig)
    rows = list(record["h_samples"])
    lanes = decode_lanes(prob, embedding, orig_from_net, config, y_samples=rows, orig_size=image.shape[:2])
    hit = real_frames.matched_lanes(lanes_to_xs(lanes, rows), record)
    where = real_frames.positions(record, image.shape[1], image.shape[0])
    parts = decode_parts(prob, embedding, orig_from_net, config)
    net_lines = [real_frames.label_in_net(xs, rows, net_from_orig) for xs in record["lanes"]]
    support = [
        real_frames.line_support(prob, p, config.prob_thresh, config.cluster_thresh or 0.0, columns) for p in net_lines
    ]
    owned = owners([line_clusters(parts, p, columns) for p in net_lines], parts["drawn"])
    lines = [
        {
            "position": w,
            "matched": h,
            "support": s,
            "owner": o,
            "cause": real_frames.miss_cause(h, s["present"], o),
        }
        for w, h, s, o in zip(where, hit, support, owned, strict=True)
        if w is not None
    ]
    numbers = {
        "raw_file": record["raw_file"],
        "drawn": len(lanes),
        "labelled": len(lines),
        "cluster_sizes": parts["sizes"],
        "lines": lines,
    }
    height, width = prob.shape
    view = cv2.warpPerspective(image, net_from_orig, (width, height), flags=cv2.INTER_AREA)
    drawn_net = [_to_net(lane, net_from_orig) for lane in lanes]
    return numbers, {"view": view, "prob": prob, "labels": net_lines, "drawn": drawn_net}


def _to_net(lane: np.ndarray, net_from_orig: np.ndarray) -> np.ndarray:
    homogeneous = np.concatenate([lane, np.ones((len(lane), 1))], axis=1) @ net_from_orig.T
    out: np.ndarray = homogeneous[:, :2] / homogeneous[:, 2:]
    return out


def picture(view: np.ndarray, panels: list[tuple[str, dict[str, Any]]]) -> np.ndarray:
    """The network's view (grey) with the labels (yellow) and each checkpoint's lanes (red, first checkpoint), then
    one probability panel per checkpoint (inferno colours; labels yellow, its lanes cyan).

    The picture is `PICTURE_SCALE` times the first checkpoint's input. A checkpoint of another input size has its
    map resized to the picture and its lines, in its own network pixels, scaled by the same factors."""
    size = (view.shape[1] * PICTURE_SCALE, view.shape[0] * PICTURE_SCALE)

    def lines(
        canvas: np.ndarray,
        polylines: list[np.ndarray],
        net_shape: tuple[int, ...],
        colour: tuple[int, int, int],
        width: int,
    ) -> None:
        scale = np.array([size[0] / net_shape[1], size[1] / net_shape[0]])  # (x, y) picture pixels per network pixel
        for line in polylines:
            if len(line) >= 2:
                pts = np.round(np.asarray(line) * scale).astype(np.int32).reshape(-1, 1, 2)
                cv2.polylines(canvas, [pts], False, colour, width, cv2.LINE_AA)

    def text(canvas: np.ndarray, words: str) -> None:
        for colour, width in (((0, 0, 0), 3), ((255, 255, 255), 1)):
            cv2.putText(canvas, words, (6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.45, colour, width, cv2.LINE_AA)

    grey = cv2.cvtColor(cv2.cvtColor(view, cv2.COLOR_BGR2GRAY), cv2.COLOR_GRAY2BGR)
    top = cv2.resize(grey, size, interpolation=cv2.INTER_NEAREST)
    first_name, first = panels[0]
    lines(top, first["labels"], view.shape, (0, 255, 255), 3)
    lines(top, first["drawn"], view.shape, (0, 0, 255), 1)
    text(top, f"labels (yellow), {first_name} (red)")
    rows = [top]
    for name, panel in panels:
        heat = cv2.applyColorMap(np.round(panel["prob"] * 255).astype(np.uint8), cv2.COLORMAP_INFERNO)
        heat = cv2.resize(heat, size, interpolation=cv2.INTER_NEAREST)
        lines(heat, panel["labels"], panel["prob"].shape, (0, 255, 255), 1)
        lines(heat, panel["drawn"], panel["prob"].shape, (255, 255, 0), 1)
        text(heat, f"{name}: lane probability, labels (yellow), its lanes (cyan)")
        rows.append(heat)
    out: np.ndarray = np.concatenate(rows, axis=0)
    return out


def tally(photos: list[dict[str, Any]]) -> dict[str, dict[str, int]]:
    """The causes counted by lane position over ``photos``."""
    out = {p: dict.fromkeys(real_frames.CAUSES, 0) for p in real_frames.POSITIONS}
    for photo in photos:
        for line in photo["lines"]:
            out[line["position"]][line["cause"]] += 1
    return out


def table(results: dict[str, Any]) -> str:
    """A markdown table: per checkpoint and position, the labelled lines by cause."""
    head = "| checkpoint | position | lines | " + " | ".join(real_frames.CAUSES) + " |"
    lines = [head, "|" + "---|" * (3 + len(real_frames.CAUSES))]
    for name, result in results.items():
        for position, causes in result["by_position"].items():
            total = sum(causes.values())
            if total:
                lines.append(
                    f"| {name} | {position} | {total} | "
                    + " | ".join(str(causes[c]) for c in real_frames.CAUSES)
                    + " |"
                )
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--ckpt", nargs="+", default=list(DEFAULT_CKPTS), help="shipped model names or checkpoints")
    parser.add_argument("--shared", type=Path, default=REPO.parent / "shared", help="the folder holding data/")
    parser.add_argument("--out", type=Path, default=Path("outputs/bench/outer-lanes"))
    parser.add_argument("--pictures", type=Path, help="write one PNG per photo here")
    parser.add_argument("--columns", type=int, default=real_frames.SUPPORT_COLUMNS, help="search half-width, columns")
    args = parser.parse_args(argv)
    from stamlane.safety.guard import GuardError, check_outputs
    from stamlane.training.quiet import quiet_libraries

    quiet_libraries()
    if args.columns < 0:
        return fail("outer_lanes", f"--columns must be >= 0, got {args.columns}")
    try:
        records, root = read_labels(args.shared)
        try:
            check_outputs(folders=[args.out, *([args.pictures] if args.pictures else [])], protected=[args.shared])
        except GuardError as err:
            raise RealRoadsError(str(err)) from None
        images = []
        for record in records:
            image = cv2.imread(str(root / record["raw_file"]))
            if image is None:
                raise RealRoadsError(f"cannot read {root / record['raw_file']}")
            images.append(image)
        results: dict[str, Any] = {}
        panels: list[list[tuple[str, dict[str, Any]]]] = [[] for _ in records]
        for ckpt in args.ckpt:
            print(f"outer_lanes: {ckpt} ...", file=sys.stderr)
            predictor = load(ckpt)
            name = Path(ckpt).stem
            photos = []
            for k, (record, image) in enumerate(zip(records, images, strict=True)):
                numbers, panel = analyse(predictor, image, record, args.columns)
                photos.append(numbers)
                panels[k].append((name, panel))
            results[name] = {
                "checkpoint": ckpt,
                "postprocess": {k: v for k, v in vars(predictor.postprocess).items()},
                "by_position": tally(photos),
                "photos": photos,
            }
    except (RealRoadsError, real_frames.RealFramesError) as err:
        return fail("outer_lanes", err)
    payload = {"split": "dev", "columns": args.columns, "present_rows": real_frames.PRESENT_ROWS, "results": results}
    write_result(args.out / "outer-lanes.json", json.loads(json.dumps(payload, default=list)), quiet=True)
    if args.pictures:
        for record, photo_panels in zip(records, panels, strict=True):
            drawn = picture(photo_panels[0][1]["view"], photo_panels)
            write_image(args.pictures / f"{Path(record['raw_file']).stem}.png", drawn, [cv2.IMWRITE_PNG_COMPRESSION, 9])
    print(table(results), end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
