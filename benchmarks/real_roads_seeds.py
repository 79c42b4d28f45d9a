"""The real-road check over seeds: `benchmarks/real_roads.py` results of several fine-tunes per recipe, side by side.

    python benchmarks/real_roads_seeds.py DIR [DIR ...] [--groups NAME ...] [--boot 10000]

Each ``DIR`` holds ``<group>-s<seed>.json`` files written by ``benchmarks/real_roads.py`` (one per checkpoint, named
after it) and, optionally, ``synthetic-test.json`` (``{"<group>-s<seed>": synthetic test F1 in %}``); several
folders are read as one (a new arm beside the committed results of its control), a run named in two of them is an
error. Per group: the real
frames' TuSimple F1, FP and FN (lane.py's), the F1 on the video's labelled frames (files written before those labels
existed leave it empty), the video's frames with more than 4 lanes, with crossing lanes, and the mean lanes per
frame, as mean ± std over seeds, each seed on its own row. Per pair of groups: the difference of
the real frames' F1, with a 95 % paired bootstrap interval over the labelled images (each image's FP and FN
averaged over the group's seeds first, then the images resampled; F1 as lane.py's, the harmonic mean of 1 - FP and
1 - FN). With six labelled images, an interval that excludes 0 is a strong difference, one that does not may still
be a real one.

Exit status 2 with one line where a ``DIR`` is no folder, a run file is unreadable, no JSON or no dev result of
``real_roads.py``, a run is in two folders, the runs were scored on different numbers of images, or ``--boot`` is out
of 1 to `MAX_BOOT`.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import warnings
from pathlib import Path

import numpy as np
from _harness import Within, fail, option_problem

SEEDED = re.compile(r"^(?P<group>.+)-s(?P<seed>\d+)$")
MAX_RUN_BYTES = 64 << 20  # a run file larger than this is no real_roads.py result
MAX_BOOT = 100_000  # bootstrap draws: each a few numpy means (~20 us), 100,000 a few seconds per pair
COLUMNS = (
    "real-frame F1",
    "FP",
    "FN",
    "video labelled F1",
    "video frames > 4 lanes",
    "crossing frames",
    "mean lanes",
    "synthetic test F1",
)


def f1(fp: float, fn: float) -> float:
    """lane.py's F1 from its FP and FN rates."""
    precision, recall = 1 - fp, 1 - fn
    return 0.0 if precision + recall == 0 else 2 * precision * recall / (precision + recall)


class SeedsError(ValueError):
    """A folder or run file that cannot be combined (one line, exit status 2)."""


def _json(path: Path) -> object:
    """The JSON of a run file (a regular file of at most `MAX_RUN_BYTES`)."""
    from stamlane.safety.guard import GuardError, read_input

    try:
        return json.loads(read_input(path, MAX_RUN_BYTES, "run file"))
    except GuardError as err:
        raise SeedsError(str(err)) from None
    except ValueError as err:
        raise SeedsError(f"{path}: not JSON ({err})") from None


def _number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def check_result(result: object, path: Path) -> dict:
    """``result`` when it is a `benchmarks/real_roads.py` dev result with the numbers `numbers` reads."""
    frames = result.get("labelled_frames") if isinstance(result, dict) else None
    video = result.get("video") if isinstance(result, dict) else None
    ok = isinstance(frames, dict) and isinstance(video, dict)
    ok = ok and all(_number(frames.get(k)) for k in ("f1", "fp", "fn"))  # type: ignore[union-attr]
    ok = ok and all(_number(video.get(k)) for k in ("frames_over_max", "frames_with_crossing", "mean_lanes"))  # type: ignore[union-attr]
    images = frames.get("per_image") if ok else None  # type: ignore[union-attr]
    ok = ok and isinstance(images, list) and len(images) > 0
    ok = ok and all(isinstance(i, dict) and _number(i.get("fp")) and _number(i.get("fn")) for i in images)  # type: ignore[union-attr]
    if not ok:
        raise SeedsError(f"{path}: not a real_roads.py dev result (labelled_frames with f1, fp, fn, per_image; video)")
    return result  # type: ignore[return-value]


def read(*folders: Path) -> dict[str, dict[int, dict]]:
    """``group -> seed -> real_roads.py result`` (plus ``"synthetic"``: the synthetic test F1 when given) of the
    runs in ``folders``, read as one.

    Raises:
        SeedsError: a folder is no folder, a run file is unreadable, no JSON or no dev result, a run is in two
            folders, or the runs were scored on different numbers of images.
    """
    groups: dict[str, dict[int, dict]] = {}
    found: dict[str, Path] = {}
    for folder in folders:
        if not folder.is_dir():
            raise SeedsError(f"{folder} is no folder of <group>-s<seed>.json files")
        synthetic_file = folder / "synthetic-test.json"
        synthetic = _json(synthetic_file) if os.path.lexists(synthetic_file) else {}
        if not isinstance(synthetic, dict) or not all(_number(v) for v in synthetic.values()):
            raise SeedsError(f"{synthetic_file}: not an object of <group>-s<seed>: synthetic test F1")
        for path in sorted(folder.glob("*.json")):
            match = SEEDED.match(path.stem)
            if match is None:
                continue
            if path.stem in found:
                raise SeedsError(f"{path.stem} is in {found[path.stem]} and in {folder}: name one of them")
            found[path.stem] = folder
            result = check_result(_json(path), path)
            result["synthetic"] = synthetic.get(path.stem, float("nan"))
            groups.setdefault(match["group"], {})[int(match["seed"])] = result
    sizes = {(g, s): len(r["labelled_frames"]["per_image"]) for g, seeds in groups.items() for s, r in seeds.items()}
    if len(set(sizes.values())) > 1:
        where = " ".join(str(f) for f in folders)
        raise SeedsError(f"{where}: the runs were scored on different numbers of images ({sizes}): not comparable")
    return groups


def numbers(result: dict) -> list[float]:
    """One seed's row: the `COLUMNS`."""
    frames, video = result["labelled_frames"], result["video"]
    return [
        100 * frames["f1"],
        100 * frames["fp"],
        100 * frames["fn"],
        100 * video["labelled_frames"]["f1"] if "labelled_frames" in video else float("nan"),  # older files: none
        video["frames_over_max"],
        video["frames_with_crossing"],
        video["mean_lanes"],
        result["synthetic"],
    ]


def table(groups: dict[str, dict[int, dict]]) -> str:
    """Markdown: per group its mean ± std over seeds, then each seed."""
    digits = (1, 1, 1, 1, 0, 0, 2, 1)
    lines = ["| fine-tune | seeds | " + " | ".join(COLUMNS) + " |", "|---" * (len(COLUMNS) + 2) + "|"]
    for name, seeds in groups.items():
        rows = np.array([numbers(seeds[s]) for s in sorted(seeds)], float)
        with warnings.catch_warnings():  # a column without a value (no synthetic test given) stays empty: "–"
            warnings.simplefilter("ignore", RuntimeWarning)
            means = np.nanmean(rows, axis=0)
            spread = np.nanstd(rows, axis=0, ddof=1) if len(rows) > 1 else np.full(len(COLUMNS), np.nan)
        # one seed has no spread: its number alone, never "± 0"
        cells = [
            "–" if np.isnan(m) else f"{m:.{d}f}" if np.isnan(s) else f"{m:.{d}f} ± {s:.{d}f}"
            for m, s, d in zip(means, spread, digits)
        ]
        lines.append(f"| **{name}** | {len(rows)} | " + " | ".join(cells) + " |")
        for seed, row in zip(sorted(seeds), rows):
            cells = ["–" if np.isnan(v) else f"{v:.{d}f}" for v, d in zip(row, digits)]
            lines.append(f"| {name}-s{seed} | 1 | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def per_image(seeds: dict[int, dict]) -> np.ndarray:
    """``(images, 2)``: each labelled image's FP and FN rates, averaged over the seeds."""
    rates = [[(i["fp"], i["fn"]) for i in seeds[s]["labelled_frames"]["per_image"]] for s in sorted(seeds)]
    mean: np.ndarray = np.array(rates, float).mean(axis=0)
    return mean


def differences(groups: dict[str, dict[int, dict]], boot: int, seed: int = 0) -> list[str]:
    """Per pair of groups: the real frames' F1 difference with its paired bootstrap interval over the images. Every
    pair draws the same resamples (a generator of its own, seeded by ``seed``): a pair's interval does not depend on
    which other groups are shown."""
    images = {name: per_image(seeds) for name, seeds in groups.items()}
    names, out = list(images), []
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            x, y = images[a], images[b]
            n, rng = len(x), np.random.default_rng(seed)
            draws = [_difference(x, y, rng.integers(0, n, n)) for _ in range(boot)]
            low, high = np.percentile(draws, [2.5, 97.5])
            whole = _difference(x, y, np.arange(n))
            out.append(f"- {a} − {b}: {whole:+.1f} [{low:+.1f}, {high:+.1f}] ({n} images resampled)")
    return out


def _difference(x: np.ndarray, y: np.ndarray, images: np.ndarray) -> float:
    """F1 points of ``x`` minus ``y`` (per-image FP and FN rates) on the ``images`` drawn."""
    return 100 * (f1(*x[images].mean(axis=0)) - f1(*y[images].mean(axis=0)))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folders", type=Path, nargs="+")
    parser.add_argument("--groups", nargs="+", help="the groups to show, in this order (default: every group)")
    parser.add_argument("--boot", type=int, default=10000, help="bootstrap draws")
    args = parser.parse_args(argv)
    if (problem := option_problem(vars(args), ranges={"boot": Within(1, MAX_BOOT)})) is not None:
        return fail("real_roads_seeds", problem)
    where = " ".join(str(f) for f in args.folders)
    try:
        groups = read(*args.folders)
    except SeedsError as err:
        return fail("real_roads_seeds", err)
    if args.groups:
        missing = [g for g in args.groups if g not in groups]
        if missing:
            return fail("real_roads_seeds", f"no <group>-s<seed>.json for {', '.join(missing)} in {where}")
        groups = {g: groups[g] for g in args.groups}
    if not groups:
        return fail("real_roads_seeds", f"no <group>-s<seed>.json in {where}")
    print(table(groups))
    print()
    print("\n".join(differences(groups, args.boot)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
