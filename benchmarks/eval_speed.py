"""Speed of stamlane-eval against the official evaluators, on generated workloads of benchmark size.

    python benchmarks/eval_speed.py [--runs 5] [--tusimple-images 2782] [--culane-images 2000]
                                    [--reference PATH ...] [--reference-python PYTHON] [--metrics tusimple culane]
                                    [--cpp PATH [--cpp-runs 3] [--core N]] [--out outputs/bench/eval_speed.json]

Goals: end to end, in one process on one core, >= 40x lane.py on TuSimple's 2782 images and >= 5x the
C++ tool on 2000 CULane images, with the same numbers. Give ``--reference lane.py`` (the official file) and
``--reference-python`` an interpreter with lane.py's own environment (numpy, scikit-learn, ujson), so that the
official script runs as its users run it.

Workloads: random road scenes (TuSimple 1280x720, 56 rows; CULane 1640x590, 4-5 lanes) with perturbed
predictions, written to a temporary folder so that file reading is timed too.

Timed (medians of ``--runs`` runs, in this process, and end to end: each tool run as a user runs it, a fresh
process with its interpreter start and imports):
- TuSimple: read both json-lines files + ``stamlane_eval.tusimple.evaluate`` (what ``stamlane-eval tusimple``
  does; reading and scoring also timed apart), against ``LaneEval.bench_one_submit`` of the official ``lane.py``
  when ``--reference lane.py`` is given (end to end: that file alone in ``--reference-python``);
  without it, against ``_ReferenceLaneEval`` below, a re-implementation of lane.py's ALGORITHM written for this
  benchmark only (the same per-image Python loops and sklearn fit), clearly not the official code.
- The floor: a fresh interpreter that only imports numpy (what any numpy evaluator pays before reading a byte);
  ``floor ratio`` is the reference's end-to-end time over it, the most any such evaluator could reach.
- CULane @ IoU 0.5: read the .lines.txt files + ``stamlane_eval.culane.evaluate`` (official C++ variant and the
  lanedet variant), against lanedet's ``culane_metric`` when ``--reference culane_metric.py`` is given.
- CULane end to end, with ``--cpp PATH``: ``stamlane-eval culane PRED GT --list LIST --iou 0.5 --format official``
  in a fresh process pinned to one core (``--core``), against the official C++ tool (its ``evaluate`` binary, built from
  cfzd/Ultra-Fast-Lane-Detection ``evaluation/culane`` @ 0915cb68, the same code as XingangPan/SCNN's
  ``tools/lane_evaluation``, with its own Makefile: ``make`` against OpenCV 4 via ``pkg-config opencv4``, which
  sets no -O flag; the source is not in this repository). It is run as its users run it, ``evaluate -a GT/ -d
  PRED/ -i IMG/ -l LIST -w 30 -t 0.5 -c 1640 -r 590 -f 1 -o OUT`` (it reads no image without ``-s``: IMG is an
  empty folder), interleaved with ours, ``--cpp-runs`` times each: on one core (``OMP_NUM_THREADS=1``, pinned to
  ``--core`` like ours: the goal's ratio, one core against one core) and with OpenMP's default threads on every
  core (for information). Its TP/FP/FN and its printed precision / recall / F (6 significant digits) must equal
  ``stamlane_eval.culane.evaluate`` on the same files, and its ``-o`` file our ``--format official`` output;
  the table's "same" column says so. Without ``--cpp``, the C++ tool's figure measured before (`CPP_SECONDS_2000`,
  docs/results/speed/README.md) is printed for comparison instead, marked as not run here.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import numpy as np
from _harness import fail, guard_out, machine, write_result
from stamlane_eval import culane, tusimple
from stamlane_eval.io import culane_entries, culane_lines_path, read_culane_lines, read_tusimple

CPP_SECONDS_2000 = 20.0  # official C++ evaluator, 2000 images @0.5, 2 threads: docs/results/speed/README.md
TUSIMPLE_GOAL = 40.0  # x lane.py, end to end: the project's goal
CULANE_GOAL = 5.0  # x the C++ tool: the project's goal
H_SAMPLES = list(range(160, 720, 10))
STAMLANE_EVAL = str(Path(sys.executable).parent / "stamlane-eval")  # the command a user runs, beside this python


# ------------------------------------------------------------------------------------------ workloads
def _scene(rng: np.random.Generator, n_lanes: int, w: float, h: float, y_top: float) -> list[np.ndarray]:
    """Lanes converging to a vanishing point: (x, y) polylines from the bottom row up to ``y_top``."""
    vx = w / 2 + rng.normal(0, w * 0.05)
    xs_bottom = np.sort(rng.uniform(-0.2 * w, 1.2 * w, n_lanes))
    lanes = []
    for xb in xs_bottom:
        ys = np.arange(h, y_top, -10.0)
        t = (h - ys) / (h - y_top + 40)
        curve = rng.normal(0, 30) * t**2
        lanes.append(np.stack([xb + (vx - xb) * t + curve, ys], axis=1))
    return lanes


def _perturb(rng: np.random.Generator, lanes: list[np.ndarray]) -> list[np.ndarray]:
    out = [
        lane + np.stack([rng.normal(0, rng.choice([2.0, 6.0, 20.0]), len(lane)), np.zeros(len(lane))], 1)
        for lane in lanes
    ]
    if out and rng.random() < 0.15:
        out.pop(int(rng.integers(len(out))))
    if rng.random() < 0.1:
        out.append(_scene(rng, 1, 1640, 590, 260)[0])
    return out


def make_tusimple(folder: Path, n: int, seed: int = 0) -> tuple[Path, Path]:
    rng = np.random.default_rng(seed)
    with open(folder / "gt.json", "w") as fg, open(folder / "pred.json", "w") as fp:
        for i in range(n):
            name = f"clips/bench/{i:05d}/20.jpg"
            gt = _scene(rng, int(rng.integers(3, 6)), 1280, 720, 240)
            pred = _perturb(rng, gt)
            g_xs = [[round(v) if v >= 0 else -2 for v in xs] for xs in tusimple.lanes_to_xs(gt, H_SAMPLES)]
            p_xs = [[round(v, 1) if v >= 0 else -2 for v in xs] for xs in tusimple.lanes_to_xs(pred, H_SAMPLES)]
            fg.write(json.dumps({"raw_file": name, "lanes": g_xs, "h_samples": H_SAMPLES}) + "\n")
            fp.write(json.dumps({"raw_file": name, "lanes": p_xs, "run_time": 10.0}) + "\n")
    return folder / "pred.json", folder / "gt.json"


def make_culane(folder: Path, n: int, seed: int = 0) -> tuple[Path, Path, Path]:
    rng = np.random.default_rng(seed)
    entries = []
    for i in range(n):
        entry = f"/driver_bench/b.MP4/{i:05d}.jpg"
        entries.append(entry)
        gt = _scene(rng, int(rng.integers(2, 5)), 1640, 590, 260)
        pred = _perturb(rng, gt)
        for root, lanes in (("anno", gt), ("pred", pred)):
            path = culane_lines_path(folder / root, entry)
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text("".join(" ".join(f"{x:.3f} {y:.0f}" for x, y in lane) + "\n" for lane in lanes))
    (folder / "list.txt").write_text("".join(e + "\n" for e in entries))
    return folder / "pred", folder / "anno", folder / "list.txt"


# ------------------------------------------------------------------------------------------ reference
_RUN_LANE_PY = (  # argv: lane.py PRED GT; runs the official LaneEval (its Python-2 __main__ block cut off)
    "import sys, types\n"
    "src = open(sys.argv[1]).read()\n"
    "mod = types.ModuleType('lane')\n"
    "exec(compile(src[: src.find('if __name__')], sys.argv[1], 'exec'), mod.__dict__)\n"
    "print(mod.LaneEval.bench_one_submit(sys.argv[2], sys.argv[3]))\n"
)


class _ReferenceLaneEval:
    """NOT the official code: lane.py's algorithm re-implemented for timing when no copy is given.

    Same structure and cost profile as the official script: per image, an sklearn LinearRegression per gt lane,
    Python list comprehensions over every row, json parsing line by line.
    """

    def __init__(self) -> None:
        from sklearn.linear_model import LinearRegression

        self.lr = LinearRegression()

    def _angle(self, xs: np.ndarray, ys: np.ndarray) -> float:
        keep = xs >= 0
        if keep.sum() > 1:
            self.lr.fit(ys[keep][:, None], xs[keep])
            return float(np.arctan(self.lr.coef_[0]))
        return 0.0

    @staticmethod
    def _line_acc(pred: list, gt: list, thr: float) -> float:
        p = np.array([v if v >= 0 else -100 for v in pred])
        g = np.array([v if v >= 0 else -100 for v in gt])
        return float(np.sum(np.where(np.abs(p - g) < thr, 1.0, 0.0))) / len(g)

    def bench(self, pred: list, gt: list, ys: list, run_time: float) -> tuple[float, float, float]:
        if run_time > 200 or len(gt) + 2 < len(pred):
            return 0.0, 0.0, 1.0
        thrs = [20 / np.cos(self._angle(np.array(g), np.array(ys))) for g in gt]
        best, matched, fn = [], 0, 0.0
        for g, thr in zip(gt, thrs, strict=True):
            accs = [self._line_acc(p, g, thr) for p in pred]
            m = max(accs) if accs else 0.0
            fn, matched = (fn + 1, matched) if m < 0.85 else (fn, matched + 1)
            best.append(m)
        fp = len(pred) - matched
        if len(gt) > 4 and fn > 0:
            fn -= 1
        s = sum(best) - (min(best) if len(gt) > 4 else 0)
        return s / max(min(4.0, len(gt)), 1.0), fp / len(pred) if pred else 0.0, fn / max(min(len(gt), 4.0), 1.0)

    def bench_one_submit(self, pred_file: str, gt_file: str) -> tuple[float, float, float]:
        preds = [json.loads(line) for line in open(pred_file)]
        gts = {g["raw_file"]: g for g in (json.loads(line) for line in open(gt_file))}
        a = f = n = 0.0
        for p in preds:
            g = gts[p["raw_file"]]
            x, y, z = self.bench(p["lanes"], g["lanes"], g["h_samples"], p["run_time"])
            a, f, n = a + x, f + y, n + z
        return a / len(gts), f / len(gts), n / len(gts)


def _load_reference(path: Path) -> ModuleType:
    """Load a copy of lane.py (its Python-2 ``__main__`` block cut off) or lanedet's culane_metric.py."""
    src = path.read_text()
    cut = src.find("if __name__")
    if cut > 0:
        src = src[:cut]
    try:
        import ujson  # noqa: F401
    except ImportError:  # lane.py imports ujson; the stdlib json has the same API for what it uses
        sys.modules["ujson"] = json
    mod = ModuleType(path.stem)
    mod.__file__ = str(path)
    exec(compile(src, str(path), "exec"), mod.__dict__)
    return mod


# ---------------------------------------------------------------------------------------------- timing
def _median(fn: Callable[[], object], runs: int) -> tuple[float, object]:
    times, out = [], None
    for _ in range(runs):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times), out


def _bench_tusimple(args: argparse.Namespace, folder: Path, refs: dict[str, Path]) -> tuple[list, dict]:
    rows: list = []
    results: dict[str, float | str] = {}
    print(f"generating {args.tusimple_images} TuSimple images ...", file=sys.stderr)
    pred_f, gt_f = make_tusimple(folder, args.tusimple_images)

    def run_ts() -> tusimple.TuSimpleResult:
        return tusimple.evaluate(read_tusimple(pred_f), read_tusimple(gt_f))

    t_ours, ours = _median(run_ts, args.runs)
    t_read, records = _median(lambda: (read_tusimple(pred_f), read_tusimple(gt_f)), args.runs)
    t_score, _ = _median(lambda: tusimple.evaluate(*records), args.runs)
    if "lane" in refs:
        lane_eval = _load_reference(refs["lane"]).LaneEval
        t_ref, ref_out = _median(lambda: lane_eval.bench_one_submit(str(pred_f), str(gt_f)), args.reference_runs)
        ref_vals = [v["value"] for v in json.loads(ref_out)]
        label = f"official lane.py ({refs['lane']})"
    else:
        ref = _ReferenceLaneEval()
        t_ref, ref_vals = _median(lambda: ref.bench_one_submit(str(pred_f), str(gt_f)), args.reference_runs)
        label = "lane.py algorithm re-implemented here (NOT the official file)"
    same = list(ref_vals) == [ours.accuracy, ours.fp, ours.fn]
    rows.append(("TuSimple", args.tusimple_images, t_ours, label, t_ref, t_ref / t_ours, same))
    results |= {
        "tusimple_s": t_ours,
        "tusimple_read_s": t_read,
        "tusimple_score_s": t_score,
        "tusimple_reference_s": t_ref,
        "tusimple_reference": label,
    }

    # end to end, as a user runs them: a fresh process each (interpreter start, imports, reading, scoring)
    command = [
        STAMLANE_EVAL,
        "tusimple",
        str(pred_f),
        str(gt_f),
        "--format",
        "json",
    ]
    t_cmd, _ = _median(lambda: subprocess.run(command, check=True, capture_output=True), args.runs)
    if "lane" in refs:  # the official file alone, in its own interpreter, as its users run it
        reference = [str(args.reference_python), "-c", _RUN_LANE_PY, str(refs["lane"]), str(pred_f), str(gt_f)]
    else:
        reference = [sys.executable, __file__, "--run-reference", str(pred_f), str(gt_f)]
    t_ref_cmd, _ = _median(lambda: subprocess.run(reference, check=True, capture_output=True), args.reference_runs)
    t_start, _ = _median(lambda: subprocess.run([sys.executable, "-c", "pass"], check=True), args.runs)
    t_numpy, _ = _median(lambda: subprocess.run([sys.executable, "-c", "import numpy"], check=True), args.runs)
    t_import, _ = _median(
        lambda: subprocess.run([sys.executable, "-c", "import stamlane_eval.cli"], check=True), args.runs
    )
    rows.append(
        ("TuSimple e2e", args.tusimple_images, t_cmd, f"{label}, own process", t_ref_cmd, t_ref_cmd / t_cmd, None)
    )
    results |= {
        "tusimple_end_to_end_s": t_cmd,
        "tusimple_reference_end_to_end_s": t_ref_cmd,
        "python_start_s": t_start,
        "numpy_floor_s": t_numpy,
        "stamlane_eval_cli_import_s": t_import - t_start,
        "tusimple_end_to_end_ratio": t_ref_cmd / t_cmd,
        "tusimple_floor_ratio": t_ref_cmd / t_numpy,
    }
    print(
        f"end to end: stamlane-eval tusimple {t_cmd:.3f} s = python start {t_start:.3f} s + importing the command "
        f"{t_import - t_start:.3f} s (numpy alone: {t_numpy - t_start:.3f} s) + reading {t_read:.3f} s + scoring "
        f"{t_score:.3f} s (+ the rest); reference {t_ref_cmd:.3f} s: {t_ref_cmd / t_cmd:.1f}x (goal "
        f"{TUSIMPLE_GOAL:g}x; floor, a process that only imports numpy: {t_ref_cmd / t_numpy:.1f}x)",
        file=sys.stderr,
    )

    return rows, results


def _pinned(core: int | None) -> Callable[[], None]:
    """A ``preexec_fn`` that pins the child (and its threads) to one core, or (None) lets it use every core, even
    when this process runs under ``taskset``."""
    cores = set(range(os.cpu_count() or 1)) if core is None else {core}
    return lambda: os.sched_setaffinity(0, cores)


def _timed(command: list[str], core: int | None, env: dict[str, str] | None = None) -> tuple[float, str]:
    """Seconds of one run of ``command`` in a fresh process (start to exit, output read), and its stdout."""
    t = time.perf_counter()
    done = subprocess.run(command, check=True, capture_output=True, text=True, env=env, preexec_fn=_pinned(core))
    return time.perf_counter() - t, done.stdout


def _parse_cpp_output(text: str) -> dict[str, float | int]:
    """The C++ tool's ``-o`` file: ``tp: N fp: N fn: N`` then ``precision: / recall: / Fmeasure:`` (6 digits)."""
    out: dict[str, float | int] = {}
    words = text.split()
    for key, name in (("tp:", "tp"), ("fp:", "fp"), ("fn:", "fn")):
        out[name] = int(words[words.index(key) + 1])
    for key, name in (("precision:", "precision"), ("recall:", "recall"), ("Fmeasure:", "f1")):
        out[name] = float(words[words.index(key) + 1])
    return out


def _culane_end_to_end(
    args: argparse.Namespace,
    folder: Path,
    cu_pred: Path,
    cu_gt: Path,
    cu_list: Path,
    ours: culane.CULaneResult,
    rows: list,
    t_in_process: float,
) -> dict[str, float | str | bool]:
    """``stamlane-eval culane`` end to end on one core, and the official C++ tool with ``--cpp`` (interleaved)."""
    core = args.core
    ours_cmd = [
        STAMLANE_EVAL,
        "culane",
        str(cu_pred),
        str(cu_gt),
        "--list",
        str(cu_list),
        "--iou",
        "0.5",
        "--format",
        "official",
    ]
    results: dict[str, float | str | bool] = {"culane_official_in_process_s": t_in_process, "core": core}
    c = ours.totals[0.5]
    if args.cpp is None:  # the C++ tool's time recorded before, against ours in process
        cpp_s = CPP_SECONDS_2000 * args.culane_images / 2000
        rows.append(
            (
                "CULane official",
                args.culane_images,
                t_in_process,
                "C++ binary, 2 threads (measured before, not run here)",
                cpp_s,
                cpp_s / t_in_process,
                None,
            )
        )
        return results
    rows.append(("CULane official", args.culane_images, t_in_process, "(in process: read + score)", None, None, None))

    (folder / "img").mkdir(exist_ok=True)  # -i: read only with -s (visualisation); an empty folder
    out_file = folder / "cpp_output.txt"
    cpp_cmd = [
        str(args.cpp),
        "-a",
        f"{cu_gt}/",
        "-d",
        f"{cu_pred}/",
        "-i",
        f"{folder / 'img'}/",
        "-l",
        str(cu_list),
        "-w",
        "30",
        "-t",
        "0.5",
        "-c",
        str(culane.CULANE_SIZE[1]),
        "-r",
        str(culane.CULANE_SIZE[0]),
        "-f",
        "1",
        "-o",
        str(out_file),
    ]
    env1 = dict(os.environ, OMP_NUM_THREADS="1")
    env_all = {k: v for k, v in os.environ.items() if k != "OMP_NUM_THREADS"}
    times: dict[str, list[float]] = {"ours": [], "cpp_1": [], "cpp_all": []}
    same = True
    ours_text = ""
    for r in range(args.cpp_runs):  # interleaved, so that the load of the shared machine hits all alike
        print(f"CULane end to end, run {r + 1}/{args.cpp_runs} ...", file=sys.stderr)
        t, ours_text = _timed(ours_cmd, core)
        times["ours"].append(t)
        for name, env, pin in (("cpp_1", env1, core), ("cpp_all", env_all, None)):
            out_file.unlink(missing_ok=True)
            times[name].append(_timed(cpp_cmd, pin, env)[0])
            text = out_file.read_text()
            cpp = _parse_cpp_output(text)
            same &= (cpp["tp"], cpp["fp"], cpp["fn"]) == (c.tp, c.fp, c.fn)
            same &= [f"{v:.6g}" for v in (cpp["precision"], cpp["recall"], cpp["f1"])] == [
                f"{v:.6g}" for v in (c.precision, c.recall, c.f1)
            ]
            same &= text.split("\n", 1)[1].strip() == ours_text.strip()  # the -o file, less its "file:" line
    t_ours, t_cpp1, t_cpp_all = (statistics.median(times[k]) for k in ("ours", "cpp_1", "cpp_all"))
    floor = statistics.median(
        _timed([sys.executable, "-c", "import stamlane_eval.cli, cv2"], core)[0] for _ in range(args.runs)
    )
    rows.append(
        (
            "CULane e2e",
            args.culane_images,
            t_ours,
            f"official C++ tool, 1 thread, core {core} (the goal)",
            t_cpp1,
            t_cpp1 / t_ours,
            same,
        )
    )
    rows.append(
        (
            "CULane e2e",
            args.culane_images,
            t_ours,
            f"official C++ tool, default threads ({os.cpu_count()} cores)",
            t_cpp_all,
            t_cpp_all / t_ours,
            same,
        )
    )
    print(
        f"end to end: stamlane-eval culane {t_ours:.2f} s on core {core} (in process, read + score: "
        f"{t_in_process:.2f} s; start + imports: {floor:.3f} s); C++ tool {t_cpp1:.2f} s on one core: "
        f"{t_cpp1 / t_ours:.1f}x (goal {CULANE_GOAL:g}x), {t_cpp_all:.2f} s with its default threads: "
        f"{t_cpp_all / t_ours:.1f}x; numbers equal: {same}",
        file=sys.stderr,
    )
    results |= {
        "cpp": str(args.cpp),
        "culane_end_to_end_s": t_ours,
        "culane_end_to_end_runs_s": times["ours"],
        "cpp_one_core_s": t_cpp1,
        "cpp_one_core_runs_s": times["cpp_1"],
        "cpp_default_threads_s": t_cpp_all,
        "cpp_default_threads_runs_s": times["cpp_all"],
        "culane_start_and_imports_s": floor,
        "culane_ratio_one_core": t_cpp1 / t_ours,
        "culane_ratio_default_threads": t_cpp_all / t_ours,
        "culane_same_numbers": same,
        "cpp_tp_fp_fn": [c.tp, c.fp, c.fn],
    }
    return results


def _bench_culane(args: argparse.Namespace, folder: Path, refs: dict[str, Path]) -> tuple[list, dict]:
    rows: list = []
    results: dict[str, float | str] = {}
    print(f"generating {args.culane_images} CULane images ...", file=sys.stderr)
    cu_pred, cu_gt, cu_list = make_culane(folder, args.culane_images)
    entries = culane_entries(cu_gt, cu_list)

    def run_cu(variant: str) -> culane.CULaneResult:
        preds = [read_culane_lines(culane_lines_path(cu_pred, e)) for e in entries]
        gts = [read_culane_lines(culane_lines_path(cu_gt, e)) for e in entries]
        return culane.evaluate(preds, gts, (0.5,), variant=variant)

    t_off, ours_off = _median(lambda: run_cu("official"), max(1, args.runs // 2))
    results |= _culane_end_to_end(args, folder, cu_pred, cu_gt, cu_list, ours_off, rows, t_off)
    t_ld, ours_ld = _median(lambda: run_cu("lanedet"), max(1, args.runs // 2))
    results |= {"culane_official_s": t_off, "culane_lanedet_s": t_ld}
    if "lanedet" in refs:
        mod = _load_reference(refs["lanedet"])

        def run_lanedet() -> tuple[int, int, int]:
            tp = fp = fn = 0
            for e in entries:
                p = mod.load_culane_img_data(str(culane_lines_path(cu_pred, e)))
                g = mod.load_culane_img_data(str(culane_lines_path(cu_gt, e)))
                r = mod.culane_metric(p, g, width=30, iou_threshold=0.5, official=True, img_shape=(590, 1640, 3))
                tp, fp, fn = tp + r[0], fp + r[1], fn + r[2]
            return tp, fp, fn

        t_ref, ref_counts = _median(run_lanedet, args.reference_runs)
        c = ours_ld.totals[0.5]
        rows.append(
            (
                "CULane lanedet",
                args.culane_images,
                t_ld,
                f"lanedet culane_metric ({refs['lanedet']})",
                t_ref,
                t_ref / t_ld,
                tuple(ref_counts) == (c.tp, c.fp, c.fn),
            )
        )
        results["culane_lanedet_reference_s"] = t_ref
    else:
        rows.append(
            ("CULane lanedet", args.culane_images, t_ld, "(give --reference culane_metric.py)", None, None, None)
        )

    return rows, results


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=5, help="runs per measurement (median reported)")
    ap.add_argument("--reference-runs", type=int, default=1, help="runs of the (slow) reference tools")
    ap.add_argument("--tusimple-images", type=int, default=2782)
    ap.add_argument("--culane-images", type=int, default=2000)
    ap.add_argument("--reference", type=Path, nargs="*", default=[], help="copies of lane.py / culane_metric.py")
    ap.add_argument(
        "--reference-python",
        type=Path,
        default=Path(sys.executable),
        help="interpreter that runs lane.py end to end (one with numpy, scikit-learn and ujson)",
    )
    ap.add_argument("--metrics", nargs="+", choices=("tusimple", "culane"), default=["tusimple", "culane"])
    ap.add_argument("--cpp", type=Path, help="the official C++ tool's evaluate binary: run it end to end")
    ap.add_argument("--cpp-runs", type=int, default=3, help="interleaved end-to-end runs of ours and the C++ tool")
    ap.add_argument(
        "--core",
        type=int,
        default=max(os.sched_getaffinity(0)),
        help="the core that one-core runs are pinned to (default: the last one this process may use)",
    )
    ap.add_argument("--out", type=Path, default=Path("outputs/bench/eval_speed.json"), help="figures as JSON")
    ap.add_argument("--run-reference", nargs=2, metavar=("PRED", "GT"), help=argparse.SUPPRESS)  # the e2e child
    args = ap.parse_args(argv)

    if (refused := guard_out("eval_speed.py", args.out)) is not None:  # before any work
        return refused
    if args.run_reference:  # one reference evaluation in this fresh process (timed from outside)
        lane = [r for r in args.reference if "LaneEval" in r.read_text()]
        evaluator = _load_reference(lane[0]).LaneEval if lane else _ReferenceLaneEval()
        print(evaluator.bench_one_submit(*args.run_reference))
        return 0
    for ref in args.reference:
        if not ref.is_file():
            return fail("eval_speed", f"{ref}: no such file")
    if args.cpp is not None and not os.access(args.cpp, os.X_OK):
        return fail("eval_speed", f"{args.cpp}: not an executable file")
    refs = {("lane" if "LaneEval" in r.read_text() else "lanedet"): r for r in args.reference}
    results: dict[str, float | str] = {}
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        if "tusimple" in args.metrics:
            r, res = _bench_tusimple(args, folder, refs)
            rows += r
            results |= res
        if "culane" in args.metrics:
            r, res = _bench_culane(args, folder / "culane", refs)
            rows += r
            results |= res

    print(f"{'metric':<16} {'images':>6} {'stamlane-eval s':>15}  {'reference':<58} {'ref s':>7} {'ratio':>6}  same")
    for name, n, t, label, tr, ratio, same in rows:
        tr_s = f"{tr:7.2f}" if tr is not None else "      -"
        ratio_s = f"{ratio:5.1f}x" if ratio is not None else "     -"
        same_s = {True: "yes", False: "NO", None: "-"}[same]
        print(f"{name:<16} {n:>6} {t:>15.3f}  {label[:58]:<58} {tr_s} {ratio_s}  {same_s}")
    print(f"(goals: TuSimple >= {TUSIMPLE_GOAL:g}x lane.py end to end; CULane >= {CULANE_GOAL:g}x the C++ tool)")
    write_result(args.out, results | machine())  # after the timings: machine() imports torch
    return 0


if __name__ == "__main__":
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    sys.exit(main())
