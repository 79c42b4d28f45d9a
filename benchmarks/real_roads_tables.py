"""The markdown tables of `benchmarks/real_roads.py`'s results: the headline numbers (dev), the lines by position and
count (dev and sealed), the sealed frames' numbers. Each row from one result JSON, as the script writes it."""

from __future__ import annotations

from pathlib import Path


def _pct(value: float | None) -> str:
    return "" if value is None else f"{100 * value:.1f}"


def _with_interval(value: float | None, interval: list[float] | None) -> str:
    if value is None:
        return "–"
    return _pct(value) + (f" [{_pct(interval[0])}, {_pct(interval[1])}]" if interval else "")


def table(results: list[dict]) -> str:
    """A markdown table of the headline numbers of each checkpoint (dev)."""
    val = any("synthetic_val" in r for r in results)
    lines = [
        "| checkpoint | "
        + ("decoding | synthetic val F1 | " if val else "")
        + "TuSimple F1 | its ceiling (crop) | accuracy | FP | FN | video: labelled F1 | lanes per frame (frames) "
        "| > 4 lanes | count changes | jitter px (median) | crossing frames |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|" + ("---|---|" if val else ""),
    ]
    for r in results:
        f, v = r["labelled_frames"], r["video"]
        hist = ", ".join(f"{k}: {n}" for k, n in v["lanes_per_frame"].items())
        video_f1 = f"{100 * v['labelled_frames']['f1']:.1f}" if "labelled_frames" in v else ""
        extra = ""
        if val:
            s = r.get("synthetic_val")
            extra = (
                f"{r.get('decoding', 'model')} | {100 * s['f1']:.1f} | " if s else f"{r.get('decoding', 'model')} | | "
            )
        lines.append(
            f"| {Path(r['checkpoint']).name} | {extra}{100 * f['f1']:.1f} | {100 * f['crop_ceiling']['f1']:.1f} "
            f"| {100 * f['accuracy']:.1f} "
            f"| {100 * f['fp']:.1f} | {100 * f['fn']:.1f} | {video_f1} | {hist} | {v['frames_over_max']} "
            f"| {v['count_changes']} "
            f"| {v['jitter_px']:.1f} ({v['jitter_px_median']:.1f}) | {v['frames_with_crossing']} |"
        )
    return "\n".join(lines) + "\n"


def lanes_table(rows: list[tuple[str, str, dict]]) -> str:
    """A markdown table of the lines by position and count: one row per ``(checkpoint, frames, numbers)``, the
    numbers those of `real_frames.lane_numbers` with lane.py's F1 (and its interval)."""
    lines = [
        "| checkpoint | frames | TuSimple F1 [95 %] | ego recall [95 %] (lines) | adjacent recall (lines) "
        "| outer recall (lines) | count error abs. [95 %] | over- / under-counted frames | > 4 lines |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name, frames, n in rows:
        pos, c = n["by_position"], n["counts"]
        cells = [
            f"{_with_interval(pos[p]['recall'], pos[p]['interval'])} ({pos[p]['matched']}/{pos[p]['labelled']})"
            for p in ("ego", "adjacent", "outer")
        ]
        error = "–" if c["mean_abs_error"] is None else f"{c['mean_abs_error']:.2f}"
        if c["mean_abs_error_interval"]:
            error += " [{:.2f}, {:.2f}]".format(*c["mean_abs_error_interval"])
        lines.append(
            f"| {name} | {frames} ({n['images']}) | {_with_interval(n['f1'], n.get('f1_interval'))} | "
            + " | ".join(cells)
            + f" | {error} | {c['over_counted']} / {c['under_counted']} | {c['over_max']} |"
        )
    return "\n".join(lines) + "\n"


def dev_lanes_rows(results: list[dict]) -> list[tuple[str, str, dict]]:
    """`lanes_table`'s rows of dev results: the photos and the video's dev frames, per checkpoint."""
    rows = []
    for r in results:
        name = Path(r["checkpoint"]).name + (f" @{r['decoding']}" if r.get("decoding", "model") != "model" else "")
        rows.append((name, "photos", r["labelled_frames"]))
        if "labelled_frames" in r["video"]:
            rows.append((name, "video, dev", r["video"]["labelled_frames"]))
    return rows


def sealed_table(results: list[dict]) -> str:
    """The sealed frames' numbers of each checkpoint: by position and count, then lane.py's numbers per stretch."""
    rows = [(Path(r["checkpoint"]).name, "video, sealed", r["video"]["labelled_frames"]) for r in results]
    lines = [
        lanes_table(rows),
        "| checkpoint | accuracy | FP | FN | " + " | ".join(f"{s}: F1 (frames)" for s in _stretches(results)) + " |",
    ]
    lines.append("|---|---|---|---|" + "---|" * len(_stretches(results)))
    for r in results:
        n = r["video"]["labelled_frames"]
        by = r["video"]["by_stretch"]
        cells = [f"{_pct(by[s]['f1'])} ({by[s]['images']})" if s in by else "" for s in _stretches(results)]
        lines.append(
            f"| {Path(r['checkpoint']).name} | {_pct(n['accuracy'])} | {_pct(n['fp'])} | {_pct(n['fn'])} | "
            + " | ".join(cells)
            + " |"
        )
    return "\n".join(lines) + "\n"


def _stretches(results: list[dict]) -> list[str]:
    names: list[str] = []
    for r in results:
        names += [s for s in r["video"]["by_stretch"] if s not in names]
    return names
