"""On-the-fly pre-alignment on the synthetic clips: how often ``estimate_clip`` recovers the true homography.

For each of ``--clips`` default synthetic clips (normal split settings, or a challenging factor's with ``--factor``), the frames
go through a JPEG round trip (as the data loader reads them), then ``stamlane.align.estimate_clip`` runs on
windows of T = 4 frames at the given strides (key frames ``--keys``, 1-based frame numbers), with the
``chain`` and ``direct`` strategies. Each history frame 1-3 steps back is compared with the generator's
exact ``key_from_hist``.

Error: the key frame's ground-region corners (rows ``0.45 H``..H-1, the alignment's default region, full
width) are taken to the history frame by the truth and back by the estimate; mean distance in key pixels
(the metric of ``benchmarks/align.py``). Success: ``ok`` and error < ``--success-px`` (2 px). Failure
reasons are counted. Times are per clip window of 4 frames, one thread.

    python benchmarks/synth_align.py [--clips 20] [--strides 1 2 3] [--set fps=10 ppm=16 world=dashcam2]
        [--preset standard|fast] [--out FILE.json]
"""

from __future__ import annotations

import argparse
import collections
import sys
import time
from dataclasses import fields, replace
from pathlib import Path

import cv2
import numpy as np
from _harness import guard_out, machine, write_image, write_result

from stamlane.align import AlignConfig, estimate_clip
from stamlane.align.homography import ALIGN_PRESETS, align_preset, default_horizon_row, ground_corners
from stamlane.synth.generator import FACTORS, SynthConfig, generate_clip


def corner_error(estimate: np.ndarray, truth: np.ndarray, shape: tuple[int, int], horizon_row: int) -> float:
    """Mean distance in key pixels of the ground corners sent to the history frame by ``truth`` and back."""
    corners = ground_corners(shape, horizon_row).reshape(-1, 1, 2)
    hist = cv2.perspectiveTransform(corners, np.linalg.inv(truth))
    back = cv2.perspectiveTransform(hist, estimate)
    return float(np.linalg.norm((back - corners).reshape(-1, 2), axis=1).mean())


def jpeg(frame: np.ndarray, quality: int) -> np.ndarray:
    return cv2.imdecode(cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, quality])[1], cv2.IMREAD_COLOR)


def parse_overrides(items: list[str]) -> dict:
    """``name=value`` pairs to ``SynthConfig`` fields (tuples as ``a,b``)."""
    names = {f.name for f in fields(SynthConfig)}
    out: dict = {}
    for item in items:
        name, _, value = item.partition("=")
        if name not in names:
            raise SystemExit(f"unknown SynthConfig field {name!r}")
        default = getattr(SynthConfig, name)
        if isinstance(default, tuple):
            out[name] = tuple(type(default[0])(float(v)) for v in value.split(","))
        elif isinstance(default, str):  # world=dashcam2
            out[name] = value
        else:
            out[name] = type(default)(float(value))
    return out


def summarise(errors: list[float], oks: list[bool], success_px: float) -> dict:
    e = np.asarray(errors)
    good = [ok and err < success_px for ok, err in zip(oks, errors, strict=True)]
    good_e = e[np.asarray(good, bool)] if any(good) else np.array([np.nan])
    return {
        "pairs": len(errors),
        "ok_rate": float(np.mean(oks)),
        "success_rate": float(np.mean(good)),
        "median_px": float(np.median(e)),
        "median_px_of_successes": float(np.median(good_e)),
        "wrong_but_ok": int(sum(ok and err >= success_px for ok, err in zip(oks, errors, strict=True))),
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--clips", type=int, default=20)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--factor", choices=tuple(FACTORS), default=None, help="a challenging factor's settings")
    p.add_argument("--strides", type=int, nargs="+", default=[1])
    p.add_argument("--keys", type=int, nargs="+", default=[20], help="key frames (1-based) of the windows")
    p.add_argument("--strategies", nargs="+", default=["chain", "direct"])
    p.add_argument("--success-px", type=float, default=2.0)
    p.add_argument("--set", nargs="*", default=[], help="SynthConfig overrides, e.g. fps=20 ppm=48")
    p.add_argument(
        "--align-set", nargs="*", default=[], help="AlignConfig overrides, e.g. max_models=1 min_working_width=0"
    )
    p.add_argument("--preset", choices=tuple(ALIGN_PRESETS), default="standard", help="the AlignConfig overridden")
    p.add_argument("--no-jpeg", action="store_true")
    p.add_argument("--dump", type=Path, default=None, help="write the frames of the first clip here (PNG)")
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args(argv)

    if (refused := guard_out("synth_align.py", args.out)) is not None:  # before any work
        return refused
    cv2.setNumThreads(1)
    overrides = parse_overrides(args.set)
    align_cfg = replace(
        align_preset(args.preset),
        **{k: type(getattr(AlignConfig, k))(float(v)) for k, v in (item.split("=") for item in args.align_set)},
    )
    cfg = SynthConfig.with_factor(args.factor, **overrides) if args.factor else SynthConfig(**overrides)
    code = 3 if args.factor else 0
    row = default_horizon_row(cfg.height)
    shape = (cfg.height, cfg.width)
    per: dict = collections.defaultdict(lambda: ([], []))
    reasons: collections.Counter = collections.Counter()
    times = []
    render = 0.0
    for c in range(args.clips):
        start = time.perf_counter()
        clip = generate_clip(cfg, np.random.default_rng([args.seed, code, c]))
        render += time.perf_counter() - start
        frames = clip.frames if args.no_jpeg else [jpeg(f, cfg.jpeg_quality) for f in clip.frames]
        if args.dump is not None and c == 0:
            for i, f in enumerate(frames):
                write_image(args.dump / f"{i + 1}.png", f)
        vehicles = bool(clip.vehicle_masks[-1].any())
        for key1 in args.keys:
            key = key1 - 1
            for stride in args.strides:
                idx = [key - stride * k for k in (3, 2, 1, 0)]
                if idx[0] < 0:
                    continue
                for strategy in args.strategies:
                    start = time.thread_time()
                    als = estimate_clip([frames[i] for i in idx], strategy=strategy, config=align_cfg)
                    times.append(time.thread_time() - start)
                    for back in (1, 2, 3):
                        al = als[3 - back]
                        truth = clip.key_from_hist(key, idx[3 - back])
                        err = corner_error(al.key_from_hist, truth, shape, row)
                        for group in ("all", "with vehicles" if vehicles else "no vehicles"):
                            per[(strategy, stride, back, group)][0].append(err)
                            per[(strategy, stride, back, group)][1].append(al.ok)
                        if not al.ok:
                            reasons[(strategy, stride, back, al.reason.split(":")[0][:60])] += 1
                        elif err >= args.success_px:
                            reasons[(strategy, stride, back, f"ok but wrong ({err:.0f} px)")] += 1
    nframes = args.clips * cfg.num_frames
    print(
        f"synthetic {cfg.width}x{cfg.height}, fps {cfg.fps}, ppm {cfg.texture_ppm}, {args.clips} clips, keys {args.keys}"
    )
    print(f"render: {nframes / render:.1f} frames/s; estimate_clip: {1000 * np.median(times):.0f} ms per 4 frames")
    print(
        "\n| strategy | stride | frames back | group | pairs | ok | success | median px | median px (successes) | wrong ok |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    results = {}
    for (strategy, stride, back, group), (errs, oks) in sorted(per.items()):
        r = summarise(errs, oks, args.success_px)
        results[f"{strategy}/s{stride}/{back}/{group}"] = r
        print(
            f"| {strategy} | {stride} | {back} | {group} | {r['pairs']} | {100 * r['ok_rate']:.0f} % | "
            f"{100 * r['success_rate']:.0f} % | {r['median_px']:.2f} | {r['median_px_of_successes']:.2f} | "
            f"{r['wrong_but_ok']} |"
        )
    print("\nfailure reasons (strategy, stride, back, reason): count")
    for k, v in sorted(reasons.items()):
        print(f"  {k}: {v}")
    if args.out:
        config = {k: str(v) for k, v in vars(args).items()}
        write_result(args.out, {"config": config, "machine": machine(), "results": results}, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
