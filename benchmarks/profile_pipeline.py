"""Where a training step and a prediction pass of the demo's recipe spend their time, stage by stage.

    python benchmarks/profile_pipeline.py [--repeats 15] [--threads 2] [--out docs/results/speed/profile_pipeline.json]
    python benchmarks/profile_pipeline.py --check docs/results/speed/profile_pipeline.json [--runs 2]  # the guard

On a small synthetic set of the demo's frame size (640x360, 20-frame clips, rendered first into a temporary
folder), with the demo's configs (`configs/demo.yaml`: 4 frames, ORB alignment ``fly``, 80x256; the CPU recipe's
key-frame corruption; bfloat16 where this CPU runs it natively) and the shipped 4-frame weights for prediction (a
trained network's lane maps, so that lane decoding costs what it costs in the demo). Every repeat times every
stage once, in turn, on the same sample, so that a busy machine slows all of them alike; each stage's figure is
the median of ``--repeats``. Stages:

- a sample (per clip, one DataLoader ``__getitem__``): ``decode`` (4 JPEGs), ``digest`` (the frames' content
  digests that key the alignment cache), ``align ORB`` (the chain of ORB + RANSAC estimates, what ``align: fly``
  paid for every clip of every new dataset), ``align cached`` (the same homographies read from the cache of
  `stamlane.data.alignment`), ``augment`` (crop, flip, resize and colour jitter of the 4 frames: what training
  does), ``resize`` (the evaluation transform alone), ``stored sample`` (a whole evaluation sample of frames read
  before, from the frame store of `stamlane.data.frame_store`: what every pass after a split's first pays),
  ``key corruption``, ``targets`` (the lane masks);
- a batch of 4: ``collate``, ``forward`` (+ the loss), ``backward``, ``optimizer`` (AdamW + the schedule), and
  in prediction ``forward eval`` (no gradients), ``decode lanes`` (per image: DBSCAN and the fits,
  `stamlane.predict.postprocess`), ``score`` (per image: TuSimple and IoU F1 of a prediction pass);
- per run or pass: ``LightningCLI`` (parsing the config and building the model and the data, paid by every
  training run and every prediction pass), ``render clip`` (one clip of the set, rendered and written).

The table gives each stage in ms and as a share of a training step (B = 4) and of a prediction pass's per-image
cost; the JSON keeps every repeat. ``--check FILE`` profiles again ``--runs`` times (default 2) and prints, per
stage, the ratio of its share now to its share in FILE (a stage that became slower relative to the others shows
there); it exits 1 when a stage's share grew more than ``--tolerance`` (default 1.5x) to at least ``--min-share``
(default 10 %) in every run; ``--result NEW [NEW ...]`` compares results written before instead of profiling now.
A guard, not a timed test: run it before and after a change of the data path. A busy machine moves the shares of a
single run (docs/results/speed/README.md says by how much), hence a stage is flagged only when every run shows it.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")  # before torch: spinning OpenMP threads starve a shared CPU

import argparse
import statistics
import sys
import tempfile
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from _harness import BenchInputError, fail, guard_out, machine, read_json_object, write_result

REPO = Path(__file__).resolve().parents[1]
SAMPLE_STAGES = ("decode", "digest", "align ORB", "align cached", "augment", "resize", "stored sample")
SAMPLE_STAGES += ("key corruption", "targets")
BATCH_STAGES = ("collate", "forward", "backward", "optimizer", "forward eval", "decode lanes", "score")
RUN_STAGES = ("LightningCLI", "render clip")
TRAIN_STEP = ("decode", "align cached", "augment", "key corruption", "targets", "collate", "forward", "backward")
TRAIN_STEP += ("optimizer",)
"""A training step of the 4-frame aligned model as it runs with the cache (per-sample stages x 4 + the batch)."""
PREDICT_IMAGE = ("stored sample", "collate", "forward eval", "decode lanes", "score")
"""The per-image cost of a prediction pass on frames read before (the frame store; batch stages / 4). The first pass
on a split pays ``decode``, ``align cached``, ``resize`` and ``targets`` instead of ``stored sample``."""
BATCH = 4


def make_set(root: Path, clips: int) -> float:
    """A small set of the demo's frame size; returns the ms of one clip rendered and written (median)."""
    from stamlane.synth import generate_dataset
    from stamlane.synth.layout import SplitCounts

    start = time.perf_counter()
    generate_dataset(root, SplitCounts(train=clips, test=clips), seed=0, progress=False, visibility=False)
    return (time.perf_counter() - start) * 1000.0 / (2 * clips)


def _cli(root: Path, *args: str):
    from stamlane.training.lightning_cli import StamLaneCLI

    argv, sys.argv = sys.argv, sys.argv[:1]
    try:
        return StamLaneCLI(
            ["--config", str(REPO / "configs" / "demo.yaml"), f"--data.root={root}", *args],
            run=False,
            parser_kwargs={"exit_on_error": False},
        )
    finally:
        sys.argv = argv


def profile(root: Path, repeats: int, render_ms: float) -> dict[str, list[float]]:
    """Every stage's times, ms, ``repeats`` each (see the module docstring)."""
    import torch

    from stamlane.align.warp import estimate_clip
    from stamlane.data.collate import collate_clips
    from stamlane.data.frame_store import FrameStore
    from stamlane.data.targets import draw_lane_targets
    from stamlane.data.transforms import ClipTransform
    from stamlane.experiments.recipes import KEY_CORRUPTION
    from stamlane.predict.writers import tusimple_record
    from stamlane.safety.checkpoints import read_checkpoint
    from stamlane.training.runs import flags_of
    from stamlane.weights import shipped_path

    times: dict[str, list[float]] = {name: [] for name in (*SAMPLE_STAGES, *BATCH_STAGES, *RUN_STAGES)}
    times["render clip"] = [render_ms]

    def timed(stage: str, fn: Callable[..., Any], *args: Any) -> Any:
        start = time.perf_counter()
        result = fn(*args)
        times[stage].append((time.perf_counter() - start) * 1000.0)
        return result

    cli = _cli(root, *flags_of(KEY_CORRUPTION))
    module, data = cli.model, cli.datamodule
    data.setup("fit")
    train, evaluation = data.datasets["train"], data.make_dataset("test")
    evaluation.frame_store = FrameStore(256 << 20)
    module.setup("fit")
    optimizer = module.optimizer_factory(module.parameters())  # the recipe's AdamW and poly schedule (no Trainer)
    scheduler = module.scheduler_factory(optimizer, 300)
    trained = _cli(root).model  # the shipped weights: a trained network's lane maps for decoding
    trained.load_state_dict(read_checkpoint(shipped_path("stam4-synthetic"))["state_dict"])
    trained.eval()
    aligner = train.aligner
    rng = np.random.default_rng(0)

    def step(loss: torch.Tensor) -> None:
        loss.backward()

    def update() -> None:
        optimizer.step()
        optimizer.zero_grad(set_to_none=True)
        scheduler.step()

    for r in range(repeats):
        timed("LightningCLI", _cli, root, *flags_of(KEY_CORRUPTION))
        entry = train.entries[(r * 7) % len(train.entries)]
        frames = timed("decode", train.read_frames, entry)
        timed("digest", aligner.digests, frames)
        timed("align ORB", estimate_clip, frames)
        aligner(entry.frame_paths, frames)  # into the cache on disk (as the first run on these frames does)
        aligner.forget()  # the in-memory memo, as in a new dataset: the cache on disk stays
        mats = timed("align cached", aligner, entry.frame_paths, frames)[0]
        h0, w0 = frames[0].shape[:2]
        params = train.transform.draw((h0, w0), rng)
        clip = timed("augment", train.transform.apply_frames, frames, mats, params)
        timed("resize", evaluation.transform.apply_frames, frames, mats, evaluation.transform.draw((h0, w0)))
        stored = evaluation.entries[r % len(evaluation.entries)]
        evaluation.load(stored, np.random.default_rng(0))  # into the store (a split's first pass)
        timed("stored sample", evaluation.load, stored, np.random.default_rng(0))
        timed("key corruption", train.key_corruption, clip.copy(), np.random.default_rng(r))
        lanes_net = ClipTransform.map_lanes(entry.lanes, params.net_from_orig)
        timed("targets", draw_lane_targets, lanes_net, train.image_size, train.thickness)
        entries = [train.entries[(r * 7 + i) % len(train.entries)] for i in range(BATCH)]
        samples = [train.load(e, np.random.default_rng(i)) for i, e in enumerate(entries)]
        batch = timed("collate", collate_clips, samples)
        module.train()
        terms = timed("forward", lambda b: module._losses(b, *module._run(b)), batch)
        timed("backward", step, terms["loss"])
        timed("optimizer", update)
        eval_batch = collate_clips([evaluation[(r * 3 + i) % len(evaluation)] for i in range(BATCH)])
        with torch.no_grad():
            logits, embedding = timed("forward eval", trained._run, eval_batch)
        metas = eval_batch["meta"]
        lanes = timed("decode lanes", trained.decode, logits, embedding, metas)
        preds = [tusimple_record(m["raw_file"], lane, m["h_samples"], 0.0) for lane, m in zip(lanes, metas)]
        gts = [tusimple_record(m["raw_file"], g, m["h_samples"], 0.0) for g, m in zip(eval_batch["lanes"], metas)]
        timed("score", _score, preds, gts, (h0, w0))
    return times


def _score(preds: list[dict], gts: list[dict], size: tuple[int, int]) -> None:
    """A prediction pass's scoring of a batch: TuSimple per image and the IoU F1 (`stamlane.experiments.split_scores`)."""
    from stamlane_eval import culane, tusimple
    from stamlane_eval.culane import IOU_THRESHOLDS
    from stamlane_eval.io import tusimple_points

    from stamlane.predict.image_score import iou_width

    tusimple.evaluate(preds, gts, time_limit=False)
    culane.evaluate(
        [tusimple_points(p["lanes"], p["h_samples"]) for p in preds],
        [tusimple_points(g["lanes"], g["h_samples"]) for g in gts],
        IOU_THRESHOLDS,
        iou_width(size),
        size,
    )


def summarise(times: dict[str, list[float]]) -> dict[str, dict[str, float]]:
    """Per stage: median ms, and its share of a training step and of a prediction pass's per-image cost."""
    med = {name: statistics.median(values) for name, values in times.items()}
    per_step = {n: med[n] * (BATCH if n in SAMPLE_STAGES else 1) for n in TRAIN_STEP}
    per_image = {n: med[n] / (1 if n in SAMPLE_STAGES else BATCH) for n in PREDICT_IMAGE}
    step, image = sum(per_step.values()), sum(per_image.values())
    return {
        name: {
            "ms": round(med[name], 3),
            "train_step_share": round(per_step[name] / step, 4) if name in per_step else None,
            "predict_image_share": round(per_image[name] / image, 4) if name in per_image else None,
        }
        for name in times
    } | {"_totals": {"train_step_ms": round(step, 2), "predict_image_ms": round(image, 2)}}


def table(summary: dict[str, dict[str, float]]) -> str:
    def pct(v: float | None) -> str:
        return "" if v is None else f"{100 * v:.1f} %"

    lines = [
        "| stage | ms (median) | share of a training step (B=4) | share of a predicted image |",
        "|---|---|---|---|",
    ]
    for name, row in summary.items():
        if name.startswith("_"):
            continue
        lines.append(
            f"| {name} | {row['ms']:.2f} | {pct(row['train_step_share'])} | {pct(row['predict_image_share'])} |"
        )
    totals = summary["_totals"]
    lines.append(f"| **training step** | {totals['train_step_ms']:.1f} | 100 % | |")
    lines.append(f"| **predicted image** | {totals['predict_image_ms']:.1f} | | 100 % |")
    return "\n".join(lines)


def check(summary: dict, reference: dict, tolerance: float, min_share: float) -> list[str]:
    """Stages whose share of a training step or a predicted image grew more than ``tolerance`` times to at least
    ``min_share`` (a stage of a few % doubled from one busy run to the next: file reads and system calls are the
    noisiest)."""
    slower = []
    for name, row in summary.items():
        for key in ("train_step_share", "predict_image_share"):
            old = reference.get(name, {}).get(key)
            if row.get(key) and old:
                ratio = row[key] / old
                print(f"{name:16s} {key:20s} {old:7.4f} -> {row[key]:7.4f}  x{ratio:.2f}")
                if ratio > tolerance and row[key] >= min_share:
                    slower.append(f"{name} ({key} x{ratio:.2f})")
    return slower


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--clips", type=int, default=4, help="clips of each of the set's two splits")
    parser.add_argument("--threads", type=int, default=2, help="torch threads (the demo: the machine's cores)")
    parser.add_argument("--out", type=Path, default=Path("outputs/benchmarks/profile_pipeline.json"))
    parser.add_argument("--check", type=Path, help="compare the shares with this earlier result; exit 1 if slower")
    parser.add_argument("--tolerance", type=float, default=1.5, help="largest growth of a stage's share")
    parser.add_argument("--min-share", type=float, default=0.1, help="smaller shares are not flagged")
    parser.add_argument(
        "--result", type=Path, nargs="+", help="with --check: compare these results instead of profiling now"
    )
    parser.add_argument("--runs", type=int, default=2, help="with --check: profiles made now, each compared")
    args = parser.parse_args(argv)

    if (refused := guard_out("profile_pipeline.py", args.out)) is not None:  # before any work
        return refused
    if args.check:
        try:  # the results compared: read (and checked) before any profile runs
            reference = read_json_object(args.check, "--check", keys=("summary",))["summary"]
            given = [read_json_object(path, "--result", keys=("summary",))["summary"] for path in args.result or ()]
        except BenchInputError as err:
            return fail("profile_pipeline.py", err)
        if args.result:
            nows = given
        else:
            nows = [_profile_now(args)[0] for _ in range(max(1, args.runs))]
        return _verdict([check(now, reference, args.tolerance, args.min_share) for now in nows], args.check)
    _, result = _profile_now(args)
    write_result(args.out, result)
    return 0


def _profile_now(args: argparse.Namespace) -> tuple[dict, dict]:
    """A profile made now: its summary and the result written to ``--out``."""
    import torch

    torch.set_num_threads(args.threads)
    info = machine()
    warnings.filterwarnings("ignore")
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "set"
        render_ms = make_set(root, args.clips)
        times = profile(root, args.repeats, render_ms)
    summary = summarise(times)
    print(table(summary))
    result = {
        **info,
        "threads": args.threads,
        "torch": torch.__version__,
        "bf16": bool(_cli_bf16()),
        "repeats": args.repeats,
        "summary": summary,
        "times_ms": times,
    }
    return summary, result


def _verdict(runs: list[list[str]], reference: Path) -> int:
    """Exit status 1 when a stage is slower in every run compared (a busy machine moves single runs)."""
    slower = [stage for stage in runs[0] if all(stage.split(" (")[0] in {s.split(" (")[0] for s in r} for r in runs)]
    if slower:
        print(f"slower than {reference} in all {len(runs)} runs: {', '.join(slower)}")
        return 1
    print(f"no stage's share grew past the tolerance against {reference}")
    return 0


def _cli_bf16() -> bool:
    from stamlane.training.hardware import native_bf16

    return native_bf16("cpu")


if __name__ == "__main__":
    sys.exit(main())
