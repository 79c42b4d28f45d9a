"""What the fusion takes from the history: the share of the fused features that the history frames contribute.

    python benchmarks/fusion_share.py outputs/demo/stam4-s0/run [--split challenging] [--data DIR] [--out FILE]

For the key frames of a split, the deepest-stage features of the key frame ``K`` and the fusion's output ``F``
(STAM in the history-carrying reading adds the gated history to ``K``: ``F - K`` is what the history brought) are
compared cell by cell of the stride-16 grid: the history's share ``|F - K| / (|F - K| + |K|)`` (L2 over channels),
on the cells a labelled lane crosses and on the others, per factor, with the real history, the key frame copied and
another clip's history. A fusion that ignores its history has a share near 0; one that reads it has a share that
changes with what the history shows. Prints a markdown table and writes json.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
import torch
from _harness import fail, guard_out, write_result

from stamlane.training.stored import StoredModel

SOURCES = ("real", "key", "other_clip")


def shares(run: Path, root: Path, split: str, source: str) -> dict[str, list[tuple[float, float]]]:
    """Per clip factor (``clean`` without one): per key frame, the history's share on lane cells and on the others."""
    model = StoredModel.open(run)  # a run folder, a checkpoint or a shipped name: read once, its own data options
    module = model.module
    data = model.datamodule(root=str(root), test_labels=[f"{split}.json"], history_source=source)
    dataset = data.make_dataset("test")
    factors = json.loads((root / "dataset.json").read_text()).get("clip_factors", {})
    captured: dict[str, torch.Tensor] = {}
    net = module.net
    net.fusion.register_forward_hook(lambda _m, inputs, output: captured.update(feats=inputs[0], fused=output))
    found: dict[str, list[tuple[float, float]]] = defaultdict(list)
    stride = int(net.encoder.total_stride)
    with torch.inference_mode():
        for i in range(len(dataset)):
            sample = dataset[i]
            module(sample["frames"][None])
            key = captured["feats"][0, -1].float()  # (C, h, w)
            history = (captured["fused"][0].float() - key).norm(dim=0)
            share = history / (history + key.norm(dim=0) + 1e-9)  # (h, w)
            lane = torch.nn.functional.max_pool2d(sample["binary"][None, None].float(), stride)[0, 0] > 0
            clip = sample["meta"]["raw_file"].split("/")[1]
            found[factors.get(clip, "clean")].append((float(share[lane].mean()), float(share[~lane].mean())))
    return found


def main(argv: list[str] | None = None) -> int:
    from stamlane.synth.generator import DEFAULT_SYNTHETIC_ROOT

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        "run", type=Path, nargs="+", help="run folders (checkpoints/last.ckpt), checkpoints or shipped names"
    )
    p.add_argument("--split", default="challenging")
    p.add_argument("--data", type=Path, default=Path(DEFAULT_SYNTHETIC_ROOT))
    p.add_argument("--out", type=Path)
    args = p.parse_args(argv)

    if (refused := guard_out("fusion_share.py", args.out)) is not None:  # before any work
        return refused
    torch.set_num_threads(2)
    results: dict[str, dict[str, list]] = {s: defaultdict(list) for s in SOURCES}
    try:
        for run in args.run:
            for source in SOURCES:
                for factor, values in shares(run, args.data, args.split, source).items():
                    results[source][factor] += values
    except (OSError, ValueError) as err:  # a checkpoint refused (CheckpointError), a split or data set not there
        return fail("fusion_share.py", err)
    print(f"history's share of the fused features (%), lane cells / other cells, {len(args.run)} run(s), {args.split}")
    print("| factor | " + " | ".join(SOURCES) + " |")
    print("|---|" + "---|" * len(SOURCES))
    for factor in results["real"]:
        cells = []
        for source in SOURCES:
            v = np.array(results[source][factor])
            cells.append(f"{100 * v[:, 0].mean():.1f} / {100 * v[:, 1].mean():.1f}")
        print(f"| {factor} | " + " | ".join(cells) + " |")
    if args.out:
        summary = {s: {f: np.mean(v, axis=0).tolist() for f, v in r.items()} for s, r in results.items()}
        write_result(args.out, {"runs": [str(r) for r in args.run], "split": args.split, "shares": summary}, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
