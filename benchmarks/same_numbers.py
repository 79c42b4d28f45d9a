"""Two experiment folders made by two versions of the code: are their numbers the same, bit for bit?

    python benchmarks/same_numbers.py BEFORE AFTER [--json report.json]

BEFORE and AFTER are the ``--out`` folders of the same ``stamlane demo`` (or ``ablate``) command, run by two
commits on the same data set, machine and thread count. What is compared, for every run and prediction folder the two
hold in common (`stamlane.experiments.store`'s layout):

- the final weights (``<run>/run/checkpoints/last.ckpt``): every tensor of the state dict, its dtype, shape and
  every bit (`torch.equal` on the raw bytes' view);
- the lanes (``predictions.json``: every line but ``run_time``, which measures the machine);
- the per-image (or per-clip) quantities (``per_image.jsonl`` / ``per_clip.jsonl``: every row, every value).

A folder in one and not the other is listed, not compared. Prints one line per difference and a last line with the
counts; exits 0 when everything compared is equal, 1 otherwise, 2 on bad input.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import torch
from _harness import fail, guard_out, write_result

ROW_FILES = ("per_image.jsonl", "per_clip.jsonl")


def _tensors(path: Path) -> dict[str, torch.Tensor]:
    from stamlane.safety.checkpoints import read_checkpoint

    state = read_checkpoint(path)["state_dict"]
    return {k: v for k, v in state.items() if isinstance(v, torch.Tensor)}


def same_weights(a: Path, b: Path) -> list[str]:
    """The names of the tensors of two checkpoints that differ in a bit, a dtype or a shape (or exist in one only)."""
    ta, tb = _tensors(a), _tensors(b)
    differ = sorted(set(ta) ^ set(tb))
    for name in sorted(set(ta) & set(tb)):
        x, y = ta[name], tb[name]
        if x.dtype != y.dtype or x.shape != y.shape:
            differ.append(name)
        elif not torch.equal(x.reshape(-1).view(torch.uint8), y.reshape(-1).view(torch.uint8)):
            differ.append(name)
    return differ


def _lines(path: Path, drop: tuple[str, ...] = ()) -> list[Any]:
    rows = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    return [{k: v for k, v in r.items() if k not in drop} if isinstance(r, dict) else r for r in rows]


def compare(before: Path, after: Path) -> dict[str, Any]:
    """What `main` prints, as data: the checkpoints and prediction folders compared, and which differ."""
    report: dict[str, Any] = {"weights": {}, "predictions": {}, "only_in_one": []}
    runs = {p.relative_to(before) for p in before.glob("*/run/checkpoints/last.ckpt")}
    runs_b = {p.relative_to(after) for p in after.glob("*/run/checkpoints/last.ckpt")}
    report["only_in_one"] += sorted(str(p) for p in runs ^ runs_b)
    for rel in sorted(runs & runs_b):
        report["weights"][str(rel.parts[0])] = same_weights(before / rel, after / rel)
    folders = {p.parent.relative_to(before) for p in before.glob("predictions/*/*/predictions.json")}
    folders_b = {p.parent.relative_to(after) for p in after.glob("predictions/*/*/predictions.json")}
    report["only_in_one"] += sorted(str(p) for p in folders ^ folders_b)
    for rel in sorted(folders & folders_b):
        differ = []
        if _lines(before / rel / "predictions.json", ("run_time",)) != _lines(
            after / rel / "predictions.json", ("run_time",)
        ):
            differ.append("predictions.json")
        for name in ROW_FILES:
            a, b = before / rel / name, after / rel / name
            if a.is_file() != b.is_file() or (a.is_file() and _lines(a) != _lines(b)):
                differ.append(name)
        report["predictions"][str(rel)] = differ
    return report


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("before", type=Path)
    p.add_argument("after", type=Path)
    p.add_argument("--json", type=Path, help="also write the report here")
    args = p.parse_args(argv)
    for folder in (args.before, args.after):
        if not folder.is_dir():
            return fail("same_numbers", f"{folder} is not a folder")
    if (refused := guard_out("same_numbers", args.json)) is not None:  # before any work
        return refused
    report = compare(args.before, args.after)
    bad = 0
    for run, tensors in report["weights"].items():
        if tensors:
            bad += 1
            print(f"{run}: {len(tensors)} tensors differ ({', '.join(tensors[:3])} ...)")
    for folder, files in report["predictions"].items():
        if files:
            bad += 1
            print(f"{folder}: {', '.join(files)} differ")
    for path in report["only_in_one"]:
        print(f"only in one of the two: {path}")
    print(
        f"{len(report['weights'])} final checkpoints and {len(report['predictions'])} prediction folders compared: "
        + ("every tensor, lane and per-image value equal" if not bad else f"{bad} differ")
    )
    if args.json:
        write_result(args.json, report, quiet=True)
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
