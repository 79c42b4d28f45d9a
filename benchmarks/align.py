"""Benchmark of the pre-alignment: accuracy, success rate and speed of ``key_from_hist``.

Pairs with a known homography:

* real 1280x720 road frames (``../shared/data/frames``) as the history frame, the key frame made by warping
  them with a ground-plane ego-motion of a pinhole camera (forward 0.5-2 m, yaw +-2 deg, pitch +-0.5 deg;
  f = 1000 px, 1.5 m above the road, vanishing line at row 280), then a brightness/contrast change,
  Gaussian noise and JPEG artefacts;
* synthetic roads rendered from two poses (``stamlane.align.synthetic``), ordinary and weak texture.

Corner error: the key frame's ground-region corners (rows ``horizon_row``..H-1, full width) are taken to the
history frame by the true homography and back by the estimate; the mean distance to where they started,
in key-frame pixels. Success: ``ok`` and corner error < 3 px. Timing: one core (``cv2.setNumThreads(1)``),
wall clock per pair including feature extraction of both frames, and per history frame inside
``align_clip`` (the key frame's features computed once per clip).

Also measured side by side: the paper's Figure 2 claim (evenly spread features vs plain ``cv2.ORB_create``
top-N), and chaining vs direct estimation for frames 1-3 back.

    python benchmarks/align.py [--pairs-per-frame 20] [--out outputs/bench/align.json]
    python benchmarks/align.py --example docs/img/align_example.png   # the README picture
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import cv2
import numpy as np
from _harness import guard_out, load_1min, machine, write_image, write_result

from stamlane.align import AlignConfig, align_clip, detect_plain_orb, detect_spread_features, estimate_homography
from stamlane.align.egomotion import RoadCamera, key_from_hist_motion
from stamlane.align.features import FeatureConfig, to_gray
from stamlane.align.homography import FramePrep, estimate_prepared, fit_homography, ground_corners, match_features
from stamlane.align.synthetic import render_road, road_texture

REPO = Path(__file__).resolve().parents[1]
FRAMES = REPO.parent / "shared" / "data" / "frames"
CAMERA = RoadCamera()  # 1280x720, f = 1000 px, 1.5 m high, vanishing line at row 280 (TuSimple-like)
HORIZON = 324  # 0.45 * 720, the default
SUCCESS_PX = 3.0
CELL = 30  # px, the cells counted as "occupied" in the Figure 2 comparison


def corner_error(estimate: np.ndarray, truth: np.ndarray, shape: tuple[int, int], horizon_row: int) -> float:
    """Mean distance in key pixels of the ground corners sent to the history frame by ``truth`` and back."""
    corners = ground_corners(shape, horizon_row).reshape(-1, 1, 2)
    hist = cv2.perspectiveTransform(corners, np.linalg.inv(truth))
    back = cv2.perspectiveTransform(hist, estimate)
    return float(np.linalg.norm((back - corners).reshape(-1, 2), axis=1).mean())


def random_motion(rng: np.random.Generator) -> tuple[float, float, float]:
    return rng.uniform(0.5, 2.0), np.radians(rng.uniform(-2, 2)), np.radians(rng.uniform(-0.5, 0.5))


def degrade(image: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Brightness/contrast change, Gaussian noise, JPEG artefacts."""
    out = image.astype(np.float32) * rng.uniform(0.8, 1.2) + rng.uniform(-20, 20)
    out += rng.normal(0, rng.uniform(1, 4), out.shape)
    out = np.clip(out, 0, 255).astype(np.uint8)
    quality = int(rng.integers(60, 91))
    return cv2.imdecode(cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, quality])[1], cv2.IMREAD_UNCHANGED)


def real_pairs(paths: list[Path], per_frame: int, rng: np.random.Generator) -> list[tuple]:
    pairs = []
    for path in paths:
        hist = cv2.imread(str(path))
        for _ in range(per_frame):
            truth = key_from_hist_motion(CAMERA, *random_motion(rng))
            key = degrade(cv2.warpPerspective(hist, truth, (hist.shape[1], hist.shape[0])), rng)
            pairs.append((hist, key, truth))
    return pairs


def synthetic_pairs(count: int, texture: float, rng: np.random.Generator) -> list[tuple]:
    pairs = []
    for i in range(count):
        tex = road_texture(int(rng.integers(1 << 30)), texture) if i % 5 == 0 else tex  # noqa: F821
        forward, yaw, pitch = random_motion(rng)
        base_yaw = np.radians(rng.uniform(-1, 1))
        hist = render_road(tex, CAMERA, yaw=base_yaw)
        key = degrade(render_road(tex, CAMERA, yaw=base_yaw + yaw, pitch=pitch, forward=forward), rng)
        pairs.append((hist, key, key_from_hist_motion(CAMERA, forward, yaw, pitch, hist_yaw=base_yaw)))
    return pairs


def summarise(
    errors: list[float], oks: list[bool], times: list[float] | None = None, walls: list[float] | None = None
) -> dict:
    errors_arr = np.array(errors)
    out = {
        "pairs": len(errors),
        "median_px": float(np.median(errors_arr)),
        "p95_px": float(np.percentile(errors_arr, 95)),
        "ok_rate": float(np.mean(oks)),
        "success_rate": float(np.mean([ok and e < SUCCESS_PX for ok, e in zip(oks, errors, strict=True)])),
    }
    if times:
        out["ms_median"] = 1000 * statistics.median(times)  # CPU time of the (single) working thread
        out["ms_min"] = 1000 * min(times)
    if walls:
        out["wall_ms_median"] = 1000 * statistics.median(walls)
    return out


def bench_pairs(pairs: list[tuple], cfg: AlignConfig) -> dict:
    errors, oks, times, walls = [], [], [], []
    for hist, key, truth in pairs:
        start, cpu = time.perf_counter(), time.thread_time()
        alignment = estimate_homography(hist, key, horizon_row=HORIZON, config=cfg)
        times.append(time.thread_time() - cpu)
        walls.append(time.perf_counter() - start)
        errors.append(corner_error(alignment.key_from_hist, truth, key.shape[:2], HORIZON))
        oks.append(alignment.ok)
    return summarise(errors, oks, times, walls)


def occupied_cells(points: np.ndarray, shape: tuple[int, int]) -> float:
    """Fraction of the ground region's 30 px cells holding at least one feature."""
    height, width = shape
    rows, cols = (height - HORIZON + CELL - 1) // CELL, (width + CELL - 1) // CELL
    cells = {(int((y - HORIZON) // CELL), int(x // CELL)) for x, y in points if y >= HORIZON}
    return len(cells) / (rows * cols)


def bench_figure2(pairs: list[tuple], budget: int = 500) -> dict:
    """Evenly spread vs plain ORB top-N, (a) alone: full resolution, one scale, cross-check, RANSAC, no
    refinement; (b) inside the whole pipeline (working scale, key pyramid, refinement)."""
    cfg = AlignConfig(refine=False)
    out = {}
    detectors = {
        "one scale: plain ORB top-N": lambda g: detect_plain_orb(g, HORIZON, budget, nlevels=1),
        "one scale: evenly spread": lambda g: detect_spread_features(g, HORIZON, FeatureConfig(max_features=budget)),
        "(ref.) cv2.ORB_create defaults, 8 levels": lambda g: detect_plain_orb(g, HORIZON, budget),
    }
    for name, detect in detectors.items():
        errors, oks, inliers, occupied, counts = [], [], [], [], []
        for hist, key, truth in pairs:
            fh, fk = detect(to_gray(hist)), detect(to_gray(key))
            src, dst = match_features(fh, fk, cfg)
            alignment = fit_homography(src, dst, key.shape[:2], HORIZON, cfg)
            errors.append(corner_error(alignment.key_from_hist, truth, key.shape[:2], HORIZON))
            oks.append(alignment.ok)
            inliers.append(alignment.num_inliers)
            occupied.append(occupied_cells(fk.points, key.shape[:2]))
            counts.append(len(fk))
        out[name] = {
            **summarise(errors, oks),
            "features": float(np.mean(counts)),
            "occupied_cells": float(np.mean(occupied)),
            "inliers_median": float(np.median(inliers)),
        }
    plain = AlignConfig(features=FeatureConfig(cell_size=15, max_features=300, spread=False))
    for name, pipeline in {
        "pipeline: plain ORB top-N": plain,
        "pipeline: evenly spread (default)": AlignConfig(),
    }.items():
        errors, oks, inliers, occupied, counts = [], [], [], [], []
        for hist, key, truth in pairs:
            hp, kp = FramePrep(hist, HORIZON, pipeline), FramePrep(key, HORIZON, pipeline)
            alignment = estimate_prepared(hp, kp, pipeline)
            errors.append(corner_error(alignment.key_from_hist, truth, key.shape[:2], HORIZON))
            oks.append(alignment.ok)
            inliers.append(alignment.num_inliers)
            occupied.append(occupied_cells(kp.features().points, key.shape[:2]))
            counts.append(len(kp.features()))
        out[name] = {
            **summarise(errors, oks),
            "features": float(np.mean(counts)),
            "occupied_cells": float(np.mean(occupied)),
            "inliers_median": float(np.median(inliers)),
        }
    return out


def make_sequence(base: np.ndarray | None, tex: np.ndarray | None, rng: np.random.Generator, length: int = 4):
    """``length`` frames, oldest first, with the exact ``key_from_hist`` of each (key last)."""
    motions = [random_motion(rng) for _ in range(length - 1)]
    forward, yaw, pitch = 0.0, 0.0, 0.0
    poses = [(0.0, 0.0, 0.0)]
    for df, dy, dp in motions:
        forward, yaw, pitch = forward + df, yaw + dy, dp
        poses.append((forward, yaw, pitch))
    frames, truths = [], []
    key_pose = poses[-1]
    for f, y, p in poses:
        # frame_from_oldest of a real frame: the ego-motion from the oldest pose; synthetic: rendered
        if base is not None:
            frame_from_oldest = key_from_hist_motion(CAMERA, f, y, p)
            frame = base if f == 0 else degrade(cv2.warpPerspective(base, frame_from_oldest, base.shape[1::-1]), rng)
        else:
            frame = degrade(render_road(tex, CAMERA, yaw=y, pitch=p, forward=f), rng)
        frames.append(frame)
    from stamlane.align.egomotion import image_from_ground

    key_from_ground = image_from_ground(CAMERA, key_pose[1], key_pose[2], key_pose[0])
    for f, y, p in poses:
        truths.append(key_from_ground @ np.linalg.inv(image_from_ground(CAMERA, y, p, f)))
    return frames, truths


def bench_chain(sequences: list[tuple]) -> dict:
    out = {}
    for strategy in ("direct", "chain"):
        per_back: dict[int, tuple[list, list]] = {1: ([], []), 2: ([], []), 3: ([], [])}
        for frames, truths in sequences:
            _, alignments = align_clip(frames, horizon_row=HORIZON, strategy=strategy)
            for back in (1, 2, 3):
                i = len(frames) - 1 - back
                per_back[back][0].append(
                    corner_error(alignments[i].key_from_hist, truths[i], frames[0].shape[:2], HORIZON)
                )
                per_back[back][1].append(alignments[i].ok)
        out[strategy] = {f"{back} back": summarise(*per_back[back]) for back in per_back}
    return out


def bench_clip_speed(sequences: list[tuple]) -> dict:
    times = []
    for frames, _ in sequences:
        cpu = time.thread_time()
        align_clip(frames, horizon_row=HORIZON)
        times.append((time.thread_time() - cpu) / (len(frames) - 1))
    return {"ms_per_history_frame_median": 1000 * statistics.median(times), "clips": len(times)}


def write_example(path: Path) -> None:
    """The README picture (``docs/img/align_example.png``): a synthetic weak-texture pair, no real frames."""
    from stamlane.align.visualize import draw_alignment

    tex = road_texture(11, 0.3)
    hist = render_road(tex, CAMERA)
    key = render_road(tex, CAMERA, forward=1.5, yaw=np.radians(1.5), pitch=np.radians(0.3))
    picture = draw_alignment(hist, key, estimate_homography(hist, key), HORIZON, scale=0.3)
    write_image(path, picture, [cv2.IMWRITE_PNG_COMPRESSION, 9])
    print(f"wrote {path}")


def fmt(row: dict, keys: tuple[str, ...]) -> str:
    def one(v: object) -> str:
        return f"{v:.3f}" if isinstance(v, float) else str(v)

    return " | ".join(one(row.get(k, "")) for k in keys)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames-dir", type=Path, default=FRAMES)
    parser.add_argument("--pairs-per-frame", type=int, default=20)
    parser.add_argument("--synthetic-pairs", type=int, default=40)
    parser.add_argument("--sequences", type=int, default=12)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=REPO / "outputs" / "bench" / "align.json")
    parser.add_argument("--example", type=Path, default=None, help="only write the synthetic example picture here")
    args = parser.parse_args(argv)

    if (refused := guard_out("align.py", args.out)) is not None:  # before any work
        return refused
    if args.example is not None:
        write_example(args.example)
        return 0
    cv2.setNumThreads(1)  # one core
    rng = np.random.default_rng(args.seed)
    paths = sorted(args.frames_dir.glob("*.jpg")) if args.frames_dir.is_dir() else []
    if not paths:
        print(f"note: no real frames in {args.frames_dir}; only synthetic pairs are measured", file=sys.stderr)
    cfg = AlignConfig()
    sets = {}
    if paths:
        sets["real frames + ego-motion"] = real_pairs(paths, args.pairs_per_frame, rng)
    sets["synthetic road"] = synthetic_pairs(args.synthetic_pairs, 1.0, rng)
    sets["synthetic weak texture"] = synthetic_pairs(args.synthetic_pairs, 0.3, rng)

    results: dict = {
        "machine": {"opencv": cv2.__version__, "load_1min_at_start": load_1min()},
        "config": repr(cfg),
        "accuracy": {},
        "ablation": {},
        "figure2": {},
        "chain_vs_direct": {},
    }
    for name, pairs in sets.items():
        results["accuracy"][name] = bench_pairs(pairs, cfg)
    first = next(iter(sets))
    results["ablation"]["match stage only (refine=False)"] = bench_pairs(sets[first], AlignConfig(refine=False))
    results["ablation"]["no key pyramid (key_scales=(1,))"] = bench_pairs(sets[first], AlignConfig(key_scales=(1.0,)))
    for name in sets:
        results["figure2"][name] = bench_figure2(sets[name][:40])
    sequences = {}
    if paths:
        sequences["real frames"] = [make_sequence(cv2.imread(str(p)), None, rng) for p in paths for _ in range(2)]
    sequences["synthetic road"] = [
        make_sequence(None, road_texture(int(rng.integers(1 << 30)), 1.0), rng) for _ in range(args.sequences)
    ]
    for name, seqs in sequences.items():
        results["chain_vs_direct"][name] = bench_chain(seqs)
    results["clip_speed"] = bench_clip_speed(next(iter(sequences.values())))

    keys = ("pairs", "median_px", "p95_px", "success_rate", "ok_rate", "ms_median")
    print(f"\n## Accuracy and speed (1280x720, one core, success = ok and error < {SUCCESS_PX} px)\n")
    print("| pairs | " + " | ".join(keys) + " |\n|---|" + "---|" * len(keys))
    for name, row in {**results["accuracy"], **{f"{first}: {k}": v for k, v in results["ablation"].items()}}.items():
        print(f"| {name} | {fmt(row, keys)} |")
    print(
        f"\nalign_clip, per history frame (key features once per clip): {results['clip_speed']['ms_per_history_frame_median']:.1f} ms"
    )
    keys2 = ("features", "occupied_cells", "inliers_median", "median_px", "p95_px", "success_rate")
    print("\n## Figure 2: evenly spread vs plain ORB top-N (alone at one scale, and inside the pipeline)\n")
    print("| pairs | detector | " + " | ".join(keys2) + " |\n|---|---|" + "---|" * len(keys2))
    for name, rows in results["figure2"].items():
        for detector, row in rows.items():
            print(f"| {name} | {detector} | {fmt(row, keys2)} |")
    keys3 = ("median_px", "p95_px", "success_rate", "ok_rate")
    print("\n## Chaining vs direct (sequences of 4 frames, 0.5-2 m per frame)\n")
    print("| sequences | strategy | frames back | " + " | ".join(keys3) + " |\n|---|---|---|" + "---|" * len(keys3))
    for name, rows in results["chain_vs_direct"].items():
        for strategy, per_back in rows.items():
            for back, row in per_back.items():
                print(f"| {name} | {strategy} | {back} | {fmt(row, keys3)} |")
    print()
    results["machine"] |= machine()  # after the timings: it imports torch
    write_result(args.out, results, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
