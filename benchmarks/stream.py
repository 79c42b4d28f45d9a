"""Streaming inference: cost per frame of streaming vs recomputing the clip vs the single-frame model, and
the accuracy of feature-space vs image-space alignment with the same trained weights.

Usage::

    python benchmarks/stream.py                                   # speed only, demo-sized net (width 0.25)
    python benchmarks/stream.py --ckpt outputs/demo/stam4/run/checkpoints/last.ckpt   # + accuracy

Speed (network only, batch 1, fp32 unless ``--bf16``; median over ``--repeats`` runs of ``--frames`` frames
after a warm-up, all variants run in rotation so that they share the machine's load, ``--threads`` intra-op
threads), per new frame of a video:

- ``single``: the model on one frame (T = 1: encoder, fusion of the key frame alone, decoder);
- ``recompute``: the clip model on the last T frames (T encoder passes; image pre-alignment not counted);
- ``stream``: `StreamingPredictor.step`: one encoder pass, T-1 cached feature maps warped by non-trivial
  homographies, fusion, decoder;

each in PyTorch and in onnxruntime (``clip.onnx`` at T and at 1; ``encoder.onnx`` + ``fuse_decode.onnx`` with
the sampling grids computed per frame). With real frames (``--frames-dir``, default the first synthetic clip)
the end-to-end loop of `StreamingPredictor` (resize, alignment, network, lane decoding) is timed too, beside
what image-space pre-alignment would add on top of the same alignment: warping T-1 more frames and encoding T.

Accuracy (needs ``--ckpt``): every clip of ``--labels`` (default the synthetic ``val.json``) is aligned once
(``stamlane.align``, chain strategy, as the data pipeline does) and run three ways with the same weights:
``image`` (history images warped before the encoder, as trained), ``feature`` (history features warped after
it, as streamed), ``none`` (no alignment); TuSimple accuracy / FP / FN / F1 by ``stamlane_eval.tusimple`` and
pixel F1 against the binary target. ``--finetune-steps N`` also continues training the checkpoint N steps
(batch 4, lr 0.005, no augmentation, on ``--finetune-labels``) twice, once with image-space and once with
feature-space alignment (the library's ``warp="image"`` / ``warp="feature"`` data and `StamLaneModule`'s
forward, as ``stamlane fit --data.clip.warp feature`` trains), and evaluates both (same data and steps, so continued
training alone is not credited to feature-space alignment).

Prints tables and writes json to ``--out`` (default ``outputs/bench/stream.json``).
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")  # before torch: spinning OpenMP threads starve a shared CPU

import argparse
import functools
import json
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import torch
from _harness import fail, guard_out, in_turn, machine, write_result
from tqdm import tqdm

from stamlane.data.clips import frame_order
from stamlane.data.collate import collate_clips
from stamlane.data.options import ClipOptions
from stamlane.data.transforms import net_homographies
from stamlane.models import STAM, LaneDecoder, LaneNet, VGGEncoder, forward_feature_aligned
from stamlane.predict.postprocess import decode_lanes
from stamlane.stream import StreamingPredictor, feature_homography, sampling_grid
from stamlane.stream.export import export_all, export_clip
from stamlane.types import NET_HOMOGRAPHIES

REPO = Path(__file__).resolve().parents[1]


def _interleaved(fns: dict[str, Callable[[], float]], repeats: int, frames: int) -> dict[str, dict[str, float]]:
    """Run every ``fn`` (which returns the seconds its timed part took for ``frames`` frames) ``repeats`` times,
    in rotation so that all see the same machine load; one warm-up run each. ms per frame: median and min."""
    for fn in fns.values():
        fn()
    times = in_turn(lambda name, _: fns[name](), list(fns), repeats)
    return {
        name: {"median": 1e3 * statistics.median(t) / frames, "min": 1e3 * min(t) / frames} for name, t in times.items()
    }


def _demo_net(width: float) -> LaneNet:
    torch.manual_seed(0)
    return LaneNet(VGGEncoder(width), functools.partial(STAM, reduction=4, reading="features"), LaneDecoder).eval()


def _homographies(num: int) -> np.ndarray:
    """Mild ground-plane-like motions in network pixels (forward motion: zoom about a low vanishing point)."""
    mats = []
    for k in range(1, num + 1):
        s = 1.0 + 0.03 * k
        mats.append(np.array([[s, 0.01 * k, -2.0 * k], [0.0, s, -6.0 * k], [0.0, 1e-4 * k, 1.0]]))
    return np.stack(mats[::-1])  # oldest (largest motion) first


def measure_speed(net: LaneNet, num_frames: int, size: tuple[int, int], frames: int, repeats: int, bf16: bool) -> dict:
    """PyTorch and onnxruntime ms per frame of single / recompute / stream (see the module docstring)."""
    height, width = size
    torch.manual_seed(1)
    video = torch.rand(frames + num_frames, 3, height, width)
    mats = _homographies(num_frames - 1)
    autocast = torch.autocast("cpu", dtype=torch.bfloat16, enabled=bf16)

    def timed(loop: Callable[[], None]) -> float:
        start = time.perf_counter()
        loop()
        return time.perf_counter() - start

    def single() -> float:
        with torch.inference_mode(), autocast:
            return timed(lambda: [net(video[k : k + 1, None]) for k in range(frames)])

    def recompute() -> float:
        with torch.inference_mode(), autocast:
            return timed(lambda: [net(video[k : k + num_frames][None]) for k in range(frames)])

    predictor = StreamingPredictor(net, num_frames, size, bf16=bf16)

    def stream() -> float:
        predictor.reset()
        for k in range(num_frames - 1):  # fill the cache (not timed)
            predictor.step(video[k])
        return timed(lambda: [predictor.step(video[num_frames - 1 + k], mats) for k in range(frames)])

    fns: dict[str, Callable[[], float]] = {"single": single, "recompute": recompute, "stream": stream}
    try:
        import onnxruntime as ort

        from stamlane.stream.onnx_runner import OnnxLaneNet
    except ImportError:  # onnxruntime missing
        return {"pytorch": _interleaved(fns, repeats, frames), "onnxruntime": {"skipped": "not installed"}}
    with tempfile.TemporaryDirectory() as tmp:
        export_all(net, tmp, num_frames, size)
        single_dir = Path(tmp) / "single"
        export_clip(net, single_dir / "clip.onnx", 1, size)
        threads = torch.get_num_threads()
        runner = OnnxLaneNet(tmp, threads=threads)
        options = ort.SessionOptions()
        options.intra_op_num_threads = threads
        single_session = ort.InferenceSession(
            str(single_dir / "clip.onnx"), options, providers=["CPUExecutionProvider"]
        )
        np_video = video.numpy()
        feat_size = (height // predictor.stride, width // predictor.stride)

        def ort_single() -> float:
            return timed(lambda: [single_session.run(None, {"clip": np_video[k : k + 1, None]}) for k in range(frames)])

        def ort_recompute() -> float:
            return timed(lambda: [runner.clip(np_video[k : k + num_frames][None]) for k in range(frames)])

        def ort_stream() -> float:
            cache = [runner.encode(np_video[k : k + 1])[-1] for k in range(num_frames - 1)]

            def loop() -> None:
                nonlocal cache
                for k in range(frames):
                    stages = runner.encode(np_video[num_frames - 1 + k : num_frames + k])
                    grid = sampling_grid(feature_homography(mats, predictor.stride), feat_size).float().numpy()
                    runner.fuse_decode(stages, np.stack(cache, axis=1), grid[None])
                    cache = [*cache[1:], stages[-1]]

            return timed(loop)

        fns |= {"ort_single": ort_single, "ort_recompute": ort_recompute, "ort_stream": ort_stream}
        times = _interleaved(fns, repeats, frames)
    return {
        "pytorch": {k: times[k] for k in ("single", "recompute", "stream")},
        "onnxruntime": {k: times[f"ort_{k}"] for k in ("single", "recompute", "stream")},
    }


def measure_end_to_end(
    net: LaneNet, num_frames: int, size: tuple[int, int], frames_dir: Path, horizon_row: int | None, bf16: bool
) -> dict:
    """Per-frame breakdown of `StreamingPredictor` on real frames, and the image-space extra on the same alignment."""
    paths = sorted(
        (p for p in frames_dir.iterdir() if p.suffix.lower() in (".jpg", ".png")), key=lambda p: frame_order(p.name)
    )
    images = [cv2.imread(str(p)) for p in paths]
    predictor = StreamingPredictor(net, num_frames, size, horizon_row=horizon_row, bf16=bf16)
    transform = predictor.transform
    stream: dict[str, list[float]] = {}
    image_space: list[float] = []
    autocast = torch.autocast("cpu", dtype=torch.bfloat16, enabled=bf16)
    for k, image in enumerate(tqdm(images, desc="end to end", unit="frame")):
        out = predictor(image)
        for name, ms in out.timings.items():
            stream.setdefault(name, []).append(ms)
        # image-space pre-alignment with the same homographies: warp + resize T frames, encode T, decode
        idx = [max(k - back, 0) for back in range(num_frames - 1, 0, -1)]
        mats = np.stack([a.key_from_hist for a in out.alignments] + [np.eye(3)])
        start = time.perf_counter()
        params = transform.draw((image.shape[1], image.shape[0]))
        clip = torch.from_numpy(transform.apply_frames([images[i] for i in idx] + [image], mats, params))
        with torch.inference_mode(), autocast:
            logits, embedding = net(clip[None])
        prob = logits.float().softmax(1)[0, 1].numpy()
        decode_lanes(prob, embedding.float()[0].numpy(), np.linalg.inv(params.net_from_orig), predictor.postprocess)
        image_space.append(1e3 * (time.perf_counter() - start))
    warm = slice(num_frames, None)  # steady state
    result = {name: statistics.median(v[warm]) for name, v in stream.items()}
    result["stream_total"] = statistics.median([sum(v[i] for v in stream.values()) for i in range(len(images))][warm])
    result["image_space_total"] = result["align"] + statistics.median(image_space[warm])
    result["frames"] = len(images)
    result["frame_size"] = [images[0].shape[1], images[0].shape[0]]
    return result


def _load(ckpt: Path) -> tuple[torch.nn.Module, ClipOptions]:
    """The StamLaneModule of a checkpoint (eval mode) and how its clips were read (flat older checkpoints too)."""
    from stamlane.data.options import ClipOptions
    from stamlane.training.stored import StoredModel

    model = StoredModel.open(ckpt)  # read once: the network and the data options it trained with
    return model.module, model.settings.clip or ClipOptions()


def _dataset(module: torch.nn.Module, clip: ClipOptions, root: Path, labels: list[str], warp: str = "image") -> object:
    from stamlane.data.layouts import TuSimpleClips

    return TuSimpleClips(
        root,
        list(labels),
        clip=ClipOptions(
            num_frames=int(module.num_frames or clip.num_frames),
            stride=clip.stride,
            image_size=tuple(module.hparams.get("image_size") or clip.image_size),
            align="fly",
            horizon_row=clip.horizon_row,
            align_strategy=clip.align_strategy,
            warp=warp,
        ),
    )


def finetune(
    module: torch.nn.Module, clip: ClipOptions, root: Path, labels: list[str], steps: int, feature: bool
) -> None:
    """Continue training ``module`` for ``steps`` SGD steps (batch 4, lr 0.005, momentum 0.9, no augmentation)
    on the clips of ``labels``, with history aligned in image space (``feature=False``) or in feature space.

    The samples are the library's (``warp="image"`` / ``warp="feature"`` data) and the forward pass is
    `StamLaneModule`'s, which runs feature-space alignment when a batch carries ``key_from_hist_net``.
    """
    dataset = _dataset(module, clip, root, labels, warp="feature" if feature else "image")
    samples = [dataset.load(entry) for entry in tqdm(dataset.entries, desc="fine-tune data", unit="clip")]
    optimizer = torch.optim.SGD(module.net.parameters(), lr=0.005, momentum=0.9, weight_decay=5e-4)
    rng = np.random.default_rng(0)
    module.train()
    for _ in tqdm(range(steps), desc=f"fine-tune ({'feature' if feature else 'image'} space)", unit="step"):
        picked = rng.choice(len(samples), size=min(4, len(samples)), replace=False)
        batch = collate_clips([samples[i] for i in picked])
        logits, embedding = module(batch["frames"], batch.get(NET_HOMOGRAPHIES))
        loss = module.loss(logits, embedding, batch["binary"], batch["instance"])
        optimizer.zero_grad()
        loss["loss"].backward()
        optimizer.step()
    module.eval()


def measure_accuracy(
    module: torch.nn.Module, clip: ClipOptions, root: Path, labels: list[str], limit: int | None
) -> dict:
    """TuSimple metrics and pixel F1 of image-space vs feature-space vs no alignment, the module's weights.

    Pixel F1: lane pixels (probability > 0.5) against the key frame's binary target at network resolution,
    counts summed over all clips.
    """
    from stamlane_eval.tusimple import evaluate, lanes_to_xs

    dataset = _dataset(module, clip, root, labels)
    num_frames, size = dataset.num_frames, dataset.image_size
    gts = {}
    for name in labels:
        for line in (root / name).read_text().splitlines():
            if line.strip():
                record = json.loads(line)
                gts[record["raw_file"]] = record
    net = module.net
    autocast = torch.autocast("cpu", dtype=torch.bfloat16, enabled=bool(module.bf16))
    preds: dict[str, list[dict]] = {"image": [], "feature": [], "none": []}
    pixels = {name: np.zeros(3, np.int64) for name in preds}  # TP, FP, FN
    entries = dataset.entries[:limit] if limit else dataset.entries
    failures = 0
    for entry in tqdm(entries, desc="accuracy", unit="clip"):
        sample = dataset.load(entry)  # image-space aligned clip and targets, as in validation
        frames = dataset.read_frames(entry)
        key_from_hist, ok = dataset.aligner(entry.frame_paths, frames)  # memoised: the same estimate
        failures += sum(not o for o in ok[:-1])
        params = dataset.transform.draw((frames[0].shape[1], frames[0].shape[0]))
        eye = np.repeat(np.eye(3)[None], len(frames), axis=0)
        aligned = sample["frames"][None]
        raw = torch.from_numpy(dataset.transform.apply_frames(frames, eye, params))[None]
        target = sample["binary"].numpy() > 0
        with torch.inference_mode(), autocast:
            outputs = {"image": net(aligned), "none": net(raw)}
            mats = torch.from_numpy(net_homographies(key_from_hist, params.net_from_orig))[None]
            outputs["feature"] = forward_feature_aligned(net, raw, mats)
        h_samples = gts[entry.raw_file]["h_samples"]
        for name, (logits, embedding) in outputs.items():
            prob = logits.float().softmax(1)[0, 1].numpy()
            lane = prob > 0.5
            pixels[name] += [int((lane & target).sum()), int((lane & ~target).sum()), int((~lane & target).sum())]
            lanes = decode_lanes(
                prob,
                embedding.float()[0].numpy(),
                np.linalg.inv(params.net_from_orig),
                module.postprocess,
                y_samples=h_samples,
                orig_size=frames[0].shape[:2],
            )
            preds[name].append({"raw_file": entry.raw_file, "lanes": lanes_to_xs(lanes, h_samples), "run_time": 0})
    gt_list = [gts[e.raw_file] for e in entries]
    result = {name: evaluate(p, gt_list).as_dict() for name, p in preds.items()}
    for name, (tp, fp, fn) in pixels.items():
        result[name]["pixel_f1"] = 2 * tp / max(2 * tp + fp + fn, 1)
        result[name]["pixel_tp_fp_fn"] = [int(tp), int(fp), int(fn)]
    result["clips"] = len(entries)
    result["alignment_failures"] = failures
    result["num_frames"] = num_frames
    result["image_size"] = list(size)
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--width", type=float, default=0.25, help="encoder width of the untrained speed model")
    parser.add_argument("--image-size", type=int, nargs=2, default=(128, 256), metavar=("H", "W"))
    parser.add_argument("--num-frames", type=int, default=4)
    parser.add_argument("--frames", type=int, default=10, help="frames per timed run")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--bf16", action="store_true", help="PyTorch under bfloat16 autocast")
    parser.add_argument("--ckpt", type=Path, help="trained checkpoint: speed of its net, and the accuracy section")
    parser.add_argument("--data-root", type=Path, default=REPO / "data" / "synthetic")
    parser.add_argument(
        "--labels", nargs="+", default=["val.json"], help="label files of the accuracy clips, under --data-root"
    )
    parser.add_argument("--limit", type=int, help="at most this many clips in the accuracy section")
    parser.add_argument(
        "--finetune-steps", type=int, default=0, help="also fine-tune the checkpoint this many steps, both ways"
    )
    parser.add_argument("--finetune-labels", nargs="+", default=["train.json"], help="clips to fine-tune on")
    parser.add_argument("--frames-dir", type=Path, help="real frames for the end-to-end timing (default: first clip)")
    parser.add_argument("--out", type=Path, default=REPO / "outputs" / "bench" / "stream.json")
    args = parser.parse_args(argv)

    if (refused := guard_out("stream.py", args.out)) is not None:  # before any work
        return refused
    torch.set_num_threads(args.threads)

    if args.ckpt is not None:
        if not args.ckpt.is_file():
            return fail("stream.py", f"checkpoint {args.ckpt} does not exist")
        module, clip = _load(args.ckpt)
        net = module.net
        num_frames = int(module.num_frames or args.num_frames)
        size = tuple(module.hparams.get("image_size") or args.image_size)
    else:
        net, num_frames, size = _demo_net(args.width), args.num_frames, tuple(args.image_size)
    report: dict = {
        "machine": {**machine(), "threads": args.threads},
        "torch": torch.__version__,
        "num_frames": num_frames,
        "image_size": list(size),
        "bf16": args.bf16,
        "model": str(args.ckpt) if args.ckpt else f"untrained VGG width {args.width}, STAM mixed C-S (features)",
    }
    report["speed_ms_per_frame"] = measure_speed(net, num_frames, size, args.frames, args.repeats, args.bf16)
    print(f"\nnetwork cost per new frame, T = {num_frames}, {size[0]}x{size[1]}, {args.threads} thread(s)")
    print("median (min) ms per frame; the ratios use the mins (least disturbed by other processes)")
    print("| runtime | single frame | recompute clip | stream | stream / single | recompute / single |")
    print("|---|---|---|---|---|---|")
    for runtime, r in report["speed_ms_per_frame"].items():
        if "stream" in r:
            med = {k: r[k]["median"] for k in ("single", "recompute", "stream")}
            low = {k: r[k]["min"] for k in ("single", "recompute", "stream")}
            r["stream_over_single"] = low["stream"] / low["single"]
            r["recompute_over_single"] = low["recompute"] / low["single"]
            r["stream_over_single_median"] = med["stream"] / med["single"]
            r["recompute_over_single_median"] = med["recompute"] / med["single"]
            cells = " | ".join(f"{med[k]:.1f} ({low[k]:.1f})" for k in ("single", "recompute", "stream"))
            print(f"| {runtime} | {cells} | {r['stream_over_single']:.2f}x | {r['recompute_over_single']:.2f}x |")

    frames_dir = args.frames_dir
    if frames_dir is None:
        clips = args.data_root / "clips"
        found = sorted(clips.iterdir()) if clips.is_dir() else []
        val = [c for c in found if c.name.startswith("val")]
        frames_dir = (val or found or [None])[0]
    if frames_dir is not None and Path(frames_dir).is_dir():
        e2e = measure_end_to_end(net, num_frames, size, Path(frames_dir), None, args.bf16)
        report["end_to_end_ms_per_frame"] = e2e
        print(f"\nend to end on {frames_dir} ({e2e['frame_size'][0]}x{e2e['frame_size'][1]}), median ms per frame")
        print("| resize | align | network | decode | stream total | image-space total (same alignment) |")
        print("|---|---|---|---|---|---|")
        print(
            f"| {e2e['preprocess']:.1f} | {e2e['align']:.1f} | {e2e['network']:.1f} | {e2e['decode']:.1f} | "
            f"{e2e['stream_total']:.1f} | {e2e['image_space_total']:.1f} |"
        )

    if args.ckpt is None:
        report["accuracy"] = "needs --ckpt (a checkpoint of `stamlane fit`, e.g. outputs/demo/**/last.ckpt)"
        print("\naccuracy of feature- vs image-space alignment: needs --ckpt")
    elif missing := [n for n in args.labels if not (args.data_root / n).is_file()]:
        report["accuracy"] = f"{args.data_root / missing[0]} does not exist"
        print(f"\naccuracy: {report['accuracy']}")
    else:
        runs = {"trained": measure_accuracy(module, clip, args.data_root, args.labels, args.limit)}
        for feature in (False, True) if args.finetune_steps else ():
            tuned, _ = _load(args.ckpt)
            finetune(tuned, clip, args.data_root, args.finetune_labels, args.finetune_steps, feature)
            name = f"finetuned_{'feature' if feature else 'image'}_space"
            runs[name] = measure_accuracy(tuned, clip, args.data_root, args.labels, args.limit)
        report["accuracy"] = runs
        if args.finetune_steps:
            report["finetune"] = {"steps": args.finetune_steps, "labels": args.finetune_labels, "batch": 4, "lr": 0.005}
        clips = runs["trained"]["clips"]
        print(f"\nmetrics on {', '.join(args.labels)} ({clips} clips), TuSimple and pixel F1")
        print("| weights | alignment | F1 | accuracy | FP | FN | pixel F1 |")
        print("|---|---|---|---|---|---|---|")
        for weights, acc in runs.items():
            for name in ("image", "feature", "none"):
                r = acc[name]
                cells = " | ".join(f"{r[k]:.4f}" for k in ("f1", "accuracy", "fp", "fn", "pixel_f1"))
                print(f"| {weights} | {name} | {cells} |")
    print()
    write_result(args.out, report, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
