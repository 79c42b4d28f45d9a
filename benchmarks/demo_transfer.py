"""How the demo's models transfer: clips of a generator seed they never saw, and real road frames.

    python benchmarks/demo_transfer.py [--demo outputs/demo] [--seed 1] [--clips 100]
                                       [--frames DIR] [--out outputs/bench/transfer]

1. Writes the test and challenging splits of a synthetic set made with master seed ``--seed`` (the demo trains
   on seed 0; the same settings otherwise), predicts them with the final weights of every run of the demo
   (``<demo>/<model>-s<seed>/run``) and scores them as the demo does: F1 per run, the 95 % interval (clips
   resampled) and the paired differences against the single-frame model.
2. With ``--frames DIR`` (1280x720 road frames, each on its own): runs every model on each frame as if the car
   stood still (the frame is its own history, so alignment is the identity) and writes ``real_frames.jpg``,
   one row per frame, one column per model. The models never saw a real frame.

Writes ``<out>/transfer.json`` and prints a table.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import cv2
import numpy as np

from stamlane.demo import MODELS, SPLITS, predict_split, score_split


def _runs(demo: Path) -> dict[str, list[Path]]:
    runs: dict[str, list[Path]] = {}
    for model in MODELS:
        found = sorted(p / "run" for p in demo.glob(f"{model.name}-s*") if (p / "run" / "checkpoints").is_dir())
        if found:
            runs[model.name] = found
    return runs


def unseen_seed(demo: Path, out: Path, seed: int, clips: int) -> dict:
    """Score every demo run on test/challenging clips of generator seed ``seed``."""
    from stamlane_eval.stats import bootstrap, f1_of_rates, paired_bootstrap

    from stamlane.synth.generator import generate_dataset

    root = out / f"synthetic-seed{seed}"
    if not (root / "dataset.json").is_file():
        generate_dataset(root, train=0, val=0, test=clips, challenging=clips, seed=seed, workers=2)
    results: dict = {"data": str(root), "seed": seed, "models": {}, "differences": []}
    rates: dict[str, dict[str, np.ndarray]] = {}
    groups: dict[str, list[str]] = {}
    for name, runs in _runs(demo).items():
        per_split: dict[str, list] = {split: [] for split in SPLITS}
        for run in runs:
            run_name = run.parent.name
            for split in SPLITS:
                pred = predict_split(run_name, run, out, split, max_overlays=4, root=root)
                scores, per_image, groups[split] = score_split(pred, root / f"{split}.json")
                per_split[split].append((scores["f1"], per_image["tusimple"]))
        rates[name] = {split: np.mean([r for _, r in per_split[split]], axis=0) for split in SPLITS}
        results["models"][name] = {
            split: {
                "f1_per_seed": [f1 for f1, _ in per_split[split]],
                "f1_ci95": list(bootstrap(rates[name][split], f1_of_rates, groups=groups[split]).interval),
            }
            for split in SPLITS
        }
    for name in rates:
        if name == "single" or "single" not in rates:
            continue
        for split in SPLITS:
            est = paired_bootstrap(rates[name][split], rates["single"][split], f1_of_rates, groups=groups[split])
            results["differences"].append(
                {"a": name, "b": "single", "split": split, "f1_diff": est.value, "ci95": list(est.interval)}
            )
    return results


def real_frames(demo: Path, frames: Path, out: Path) -> Path:
    """``<out>/real_frames.jpg``: every model's lanes on each real frame (the frame as its own history)."""
    from stamlane.checkpoints import load_module, read_checkpoint
    from stamlane.overlay import draw_lanes
    from stamlane.stream import StreamingPredictor

    images = sorted(p for p in frames.iterdir() if p.suffix.lower() in (".jpg", ".png"))
    predictors = []
    for name, runs in _runs(demo).items():
        ckpt = runs[0] / "checkpoints" / "last.ckpt"
        module = load_module(ckpt)
        data = read_checkpoint(ckpt).get("datamodule_hyper_parameters") or {}
        crop_top = module.hparams.get("crop_top") or data.get("crop_top") or 0.0  # older runs: the data's
        predictor = StreamingPredictor.from_module(module, crop_top=float(crop_top))
        predictors.append((name, predictor))
    rows = []
    for path in images:
        image = cv2.imread(str(path))
        cells = []
        for name, predictor in predictors:
            predictor.reset()
            for _ in range(predictor.num_frames):
                output = predictor(image)
            cell = draw_lanes(image.copy(), output.lanes)
            cv2.putText(cell, name, (16, 48), cv2.FONT_HERSHEY_SIMPLEX, 1.4, (255, 255, 255), 3, cv2.LINE_AA)
            cells.append(cv2.resize(cell, (640, 360), interpolation=cv2.INTER_AREA))
        rows.append(np.concatenate(cells, axis=1))
    path = out / "real_frames.jpg"
    cv2.imwrite(str(path), np.concatenate(rows, axis=0), [cv2.IMWRITE_JPEG_QUALITY, 85])
    return path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--demo", type=Path, default=Path("outputs/demo"), help="the demo's output folder")
    parser.add_argument("--seed", type=int, default=1, help="generator seed of the unseen clips")
    parser.add_argument("--clips", type=int, default=100, help="clips per split (5 key frames each)")
    parser.add_argument("--frames", type=Path, default=None, help="a folder of real road frames")
    parser.add_argument("--out", type=Path, default=Path("outputs/bench/transfer"))
    args = parser.parse_args(argv)
    if not _runs(args.demo):
        print(f"demo_transfer: no demo runs under {args.demo} (run `stamlane demo` first)", file=sys.stderr)
        return 2
    args.out.mkdir(parents=True, exist_ok=True)
    results = unseen_seed(args.demo, args.out, args.seed, args.clips)
    if args.frames is not None:
        results["real_frames"] = str(real_frames(args.demo, args.frames, args.out))
    (args.out / "transfer.json").write_text(json.dumps(results, indent=2))
    print(f"clips of generator seed {args.seed} (never seen in training): TuSimple F1 %, [95 % interval]")
    for name, splits in results["models"].items():
        cells = [
            f"{split} {100 * np.mean(s['f1_per_seed']):.1f} [{100 * s['f1_ci95'][0]:.1f}, {100 * s['f1_ci95'][1]:.1f}]"
            for split, s in splits.items()
        ]
        print(f"  {name:<14} " + "   ".join(cells))
    for d in results["differences"]:
        print(
            f"  {d['a']} - {d['b']} {d['split']}: {100 * d['f1_diff']:+.1f} "
            f"[{100 * d['ci95'][0]:+.1f}, {100 * d['ci95'][1]:+.1f}]"
        )
    print(f"wrote {args.out / 'transfer.json'}" + (f" and {results['real_frames']}" if args.frames else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
