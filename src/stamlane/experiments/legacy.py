"""Summaries written by ``stamlane demo`` before the typed summary (format 1), read as format 2.

Format 1 kept a model's TuSimple F1 at ``entry[split]`` and ``entry["factors"][factor]`` and its IoU F1 under
``entry["iou@0.5"]``; differences under ``comparisons`` (TuSimple) and ``iou_comparisons`` (each naming its
``metric``). The oldest ones lack ``images``, ``configs``, the IoU F1 or the intervals over seeds: what is missing
stays missing. Nothing is recomputed: the numbers are the ones the file holds.
"""

from __future__ import annotations

from typing import Any

__all__ = ["convert_format_1"]

_METRIC = {"tusimple": "tusimple_f1", "iou@0.5": "culane_f1@0.5", "iou@0.3": "culane_f1@0.3"}
_SPLITS = ("test", "challenging")


def _value(old: dict) -> dict:
    return {
        "mean": old["f1_mean"],
        "std": old.get("f1_std"),
        "ci95": old.get("f1_ci95"),
        "seeds": old.get("seeds", 1),
        "images": old.get("images", 0),
    }


def _values(block: dict) -> dict:
    """``{split: v, "factors": {factor: v}}`` (format 1) -> ``{view: value}``."""
    found = {split: _value(block[split]) for split in _SPLITS if split in block}
    for factor, v in block.get("factors", {}).items():
        found[f"challenging:{factor}"] = _value(v)
    return found


def _seed_diffs(a: dict[int, dict], b: dict[int, dict], split: str) -> dict[str, Any]:
    """The per-seed TuSimple F1 differences of a whole split from the runs' own scores (summaries written before
    the demo kept them), with their interval; nothing for one seed."""
    from stamlane_eval.stats import seed_interval

    seeds = sorted(set(a) & set(b))
    if len(seeds) < 2 or any(split not in a[s] or split not in b[s] for s in seeds):
        return {}
    diffs = [a[s][split]["f1"] - b[s][split]["f1"] for s in seeds]
    return {"seed_diffs": diffs, "seed_ci95": list(seed_interval(diffs).interval)}


def _view(split: str) -> str:
    return split  # format 1 named factor views "challenging:<factor>" already


def convert_format_1(data: dict[str, Any]) -> dict[str, Any]:
    """A format-1 summary as the json form of format 2 (see the module docstring)."""
    models = []
    for m in data["models"]:
        values = {"tusimple_f1": _values(m)}
        for old, new in _METRIC.items():
            if old in m:
                values[new] = _values(m[old])
        runs = [
            {
                "seed": r["seed"],
                "train_minutes": r.get("train_minutes", 0.0),
                "run": r.get("run", ""),
                "last_ckpt": r.get("last_ckpt", ""),
                "frames": r.get("frames", m.get("frames", 0)),
                "scores": {split: r[split] for split in _SPLITS if split in r},
            }
            for r in m.get("runs", [])
        ]
        models.append(
            {
                "name": m["name"],
                "label": m.get("label", m["name"]),
                "paper_row": m.get("paper_row"),
                "configs": m.get("configs", [m["config"]] if "config" in m else []),
                "frames": m.get("frames", 0),
                "steps": m.get("steps", data.get("steps", 0)),
                "runs": runs,
                "values": values,
            }
        )
    differences = []
    runs = {m["name"]: {r["seed"]: r for r in m.get("runs", [])} for m in data["models"]}
    for c in [*data.get("comparisons", []), *data.get("iou_comparisons", [])]:
        if "seed_diffs" not in c and "metric" not in c and c["split"] in _SPLITS:
            c = c | _seed_diffs(runs[c["a"]], runs[c["b"]], c["split"])
        differences.append(
            {
                "kind": "models",
                "a": c["a"],
                "b": c["b"],
                "view": _view(c["split"]),
                "metric": _METRIC[c.get("metric", "tusimple")],
                "diff": c["f1_diff"],
                "ci95": c["ci95"],
                "seed_diffs": c.get("seed_diffs", []),
                "seed_ci95": c.get("seed_ci95"),
            }
        )
    pictures = {k: data[k] for k in ("val_f1_plot", "comparison") if data.get(k)}
    return {
        "data": data.get("data", ""),
        "splits_sha256": {},
        "seeds": data.get("seeds", []),
        "recipe": {
            "name": "cpu",
            "pretrain_steps": data.get("pretrain_steps"),
            "steps": data.get("finetune_steps"),
        },
        "bf16": data.get("bf16", False),
        "iou_width": data.get("iou_width"),
        "models": models,
        "differences": differences,
        "minutes": data.get("minutes"),
        "pictures": pictures,
        "format": 2,
    }
