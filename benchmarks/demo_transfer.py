"""How the demo's models transfer: clips of a generator seed they never saw, and real road frames.

    python benchmarks/demo_transfer.py [--demo outputs/demo] [--seed 1] [--clips 100]
                                       [--frames DIR] [--out outputs/bench/transfer]

1. Writes the test and challenging splits of a synthetic set made with master seed ``--seed`` (the demo trains
   on seed 0; the same settings otherwise), predicts them with the final weights of every finished run of the
   demo (its run store, `stamlane.experiments.store.RunStore`) and scores them as the demo does
   (`stamlane.experiments.runner.Runner.score`): F1 per run, the 95 % interval (clips resampled) and the paired
   differences against the single-frame model.
2. With ``--frames DIR`` (1280x720 road frames, each on its own): runs every model on each frame as if the car
   stood still (the frame is its own history, so alignment is the identity) and writes ``real_frames.jpg``,
   one row per frame, one column per model. The models never saw a real frame.

Writes ``<out>/transfer.json`` and prints a table.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np
from _harness import fail, guard_out, write_image, write_result

from stamlane.experiments.demo import MODELS
from stamlane.experiments.store import RunStore

SPLITS = ("test", "challenging")


def _runs(demo: Path) -> dict[str, list[int]]:
    """The seeds of the finished runs of the demo's models under ``demo`` (its run store), per model."""
    store = RunStore(demo)
    found = {model.name: store.seeds(model.name) for model in MODELS}
    return {model: seeds for model, seeds in found.items() if seeds}


def unseen_seed(demo: Path, out: Path, seed: int, clips: int) -> dict:
    """Score every demo run on test/challenging clips of generator seed ``seed``, as the demo scores its own."""
    from dataclasses import asdict

    from stamlane.experiments.intervals import Scores, views
    from stamlane.experiments.metrics import TUSIMPLE_F1
    from stamlane.experiments.runner import Runner, frames_of
    from stamlane.synth import generate_dataset
    from stamlane.synth.layout import SplitCounts
    from stamlane.training.runs import RunRecord

    root = out / f"synthetic-seed{seed}"
    if not (root / "dataset.json").is_file():
        generate_dataset(root, SplitCounts(test=clips, challenging=clips), seed=seed, workers=2)
    runs, runner = RunStore(demo), Runner(RunStore(out), root, max_overlays=4)  # the demo's runs, predicted here
    scores = Scores()
    for model, seeds in _runs(demo).items():
        for seed in seeds:
            name = runs.run_name(model, seed)
            run = runs.run_dir(name)
            # scored on these clips, not kept in the demo's
            record = RunRecord(run, runs.last_ckpt(name), frames_of(run), seed, train_minutes=0.0)
            runner.score(name, record, dict.fromkeys(SPLITS, ()))
            for split in SPLITS:
                per_image, groups = runner.scored(name, record, split)
                scores.add(model, split, seed, per_image, groups)
    all_views = views(root, scores.clips)
    names = list(scores.quantities)
    pairs = [(name, "single") for name in names if name != "single" and "single" in names]
    return {
        "data": str(root),
        "seed": seed,
        "models": {
            name: {
                k: {v: asdict(x) for v, x in d.items()}
                for k, d in scores.values(name, all_views, (TUSIMPLE_F1,)).items()
            }
            for name in names
        },
        "differences": [asdict(d) for d in scores.differences("models", pairs, all_views, (TUSIMPLE_F1,))],
    }


def real_frames(demo: Path, frames: Path, out: Path) -> Path:
    """``<out>/real_frames.jpg``: every model's lanes on each real frame (the frame as its own history)."""
    from stamlane.predict.overlay import draw_lanes
    from stamlane.stream import StreamingPredictor
    from stamlane.training.stored import StoredModel

    images = sorted(p for p in frames.iterdir() if p.suffix.lower() in (".jpg", ".png"))
    store = RunStore(demo)
    predictors = []
    for name, seeds in _runs(demo).items():
        ckpt = store.last_ckpt(store.run_name(name, seeds[0]))
        predictor = StreamingPredictor.from_stored(StoredModel.open(ckpt))
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
    write_image(path, np.concatenate(rows, axis=0), [cv2.IMWRITE_JPEG_QUALITY, 85])
    return path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--demo", type=Path, default=Path("outputs/demo"), help="the demo's output folder")
    parser.add_argument("--seed", type=int, default=1, help="generator seed of the unseen clips")
    parser.add_argument("--clips", type=int, default=100, help="clips per split (5 key frames each)")
    parser.add_argument("--frames", type=Path, default=None, help="a folder of real road frames")
    parser.add_argument("--out", type=Path, default=Path("outputs/bench/transfer"))
    args = parser.parse_args(argv)

    if (refused := guard_out("demo_transfer.py", args.out, folder=True)) is not None:  # before any work
        return refused
    if not _runs(args.demo):
        return fail("demo_transfer", f"no demo runs under {args.demo} (run `stamlane demo` first)")
    from stamlane.training.quiet import quiet_libraries

    quiet_libraries()  # as the demo: Lightning's per-call chatter would bury the progress lines
    args.out.mkdir(parents=True, exist_ok=True)
    results = unseen_seed(args.demo, args.out, args.seed, args.clips)
    if args.frames is not None:
        results["real_frames"] = str(real_frames(args.demo, args.frames, args.out))
    write_result(args.out / "transfer.json", results, indent=2, quiet=True)
    print(f"clips of generator seed {args.seed} (never seen in training): TuSimple F1 %, [95 % interval]")
    for name, values in results["models"].items():
        cells = [
            f"{split} {100 * v['mean']:.1f} [{100 * v['ci95'][0]:.1f}, {100 * v['ci95'][1]:.1f}]"
            for split, v in values["tusimple_f1"].items()
            if split in SPLITS
        ]
        print(f"  {name:<14} " + "   ".join(cells))
    for d in results["differences"]:
        if d["view"] in SPLITS:
            print(
                f"  {d['a']} - {d['b']} {d['view']}: {100 * d['diff']:+.1f} [{100 * d['ci95'][0]:+.1f}, {100 * d['ci95'][1]:+.1f}]"
            )
    print(f"wrote {args.out / 'transfer.json'}" + (f" and {results['real_frames']}" if args.frames else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
