"""Speed of the temporal stability metric (Rs/Rj/Rm) against RVLD's evaluate_temporal.py, in the same run.

    python benchmarks/video_speed.py [--frames 10000] [--sequence-length 100] [--size 1920x1080]
                                     [--pred-points rvld|N] [--runs 3] [--jobs N] [--reference evaluate_temporal.py]
                                     [--reference-frames 100] [--out outputs/bench/video_speed.json]

Workload: VIL-100-like sequences (1920x1080 frames, 100 frames a video as VIL-100's, 3-5 annotated lanes of
30-60 points written with one decimal as its anno_txt; predictions perturbed, sometimes missed, sometimes a false
lane, written with three decimals as RVLD writes them), in a temporary folder in the CULane layout so that
reading is timed too. Predicted points: ``rvld`` (default) puts them where RVLD's VIL-100 code does, at its 100
node rows (``config.py``: ``py_coord`` of the 384-row network input, ``crop_size`` 120, mapped to the frame by
``rescale_pts``), only the nodes within the lane's height (``height_idx``): 65-81 points here; ``N``: N points
evenly from the bottom row to the lane's top (the workload of the first figures, 100). The time grows with the
points drawn: every lane is resampled to (points - 1) * 5 + 1 points and drawn 30 px wide segment by segment,
as the script does.

Timed in this process, one core, the garbage collector off as ``stamlane-eval`` runs it (medians of ``--runs``):
read every ``.lines.txt`` + ``stamlane_eval.temporal.evaluate`` at IoU 0.5, on all ``--frames``; then each stage
alone on the same lanes (reading; the points as the script keeps them; the splines, FITPACK through scipy; the
drawing, and OpenCV's ``polylines`` calls of it alone; what is left is the IoU of the crops and the Hungarian
matching). Reading, the splines and OpenCV's drawing are the floor of any implementation that reproduces the
script's pixels with scipy and OpenCV. ``--jobs N`` also times the sequences spread over N processes (wall time:
what a user with N free cores waits).
With ``--reference``, the VIL-100 copy of RVLD's script
(``Modeling/VIL-100/PLD/code/evaluation/evaluate_temporal.py``) is run unmodified on the first
``--reference-frames`` frames (its ``LaneEval_Temporal.measure_IoU``, which draws every lane on a full
(H, W, 3) image and is far slower), with the I/O glue it needs (``libs.utils`` pickle helpers, ``p_tqdm.p_map``
in-process, its folders and pickles); stamlane-eval is timed on the same frames, side by side, the ratio
printed and the numbers compared.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import io
import os
import pickle
import statistics
import sys
import tempfile
import time
import types
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
from _harness import fail, guard_out, machine, write_result
from stamlane_eval import temporal
from stamlane_eval.io import read_culane_lines
from stamlane_eval.video import Frame

VIL100_SIZE = "1920x1080"  # WxH of most VIL-100 videos


# ------------------------------------------------------------------------------------------- workload
def _lane(xb: float, vx: float, ys: np.ndarray, y_top: float, bend: float) -> np.ndarray:
    """A lane from ``(xb, ys[0])`` bending towards ``(vx, y_top)``, at the rows ``ys`` (bottom first)."""
    h = ys[0]
    t = (h - ys) / (h - y_top)
    return np.stack([xb + (vx - xb) * t + bend * t * (1 - t), ys], axis=1)


def rvld_node_rows(height: int) -> np.ndarray:
    """The frame rows of RVLD's 100 lane nodes (VIL-100 ``config.py`` + ``save_prediction.rescale_pts``),
    bottom first: ``py_coord`` on the 384-row input (rows 54..383 of it, 100 of the 330 sampled), the 120
    cropped rows added back, scaled to the frame's ``height``."""
    net_h, crop, max_y, nodes = 384, 120, 330, 100
    py = net_h - np.float32(np.round(np.linspace(max_y, 1, max_y)))
    py = py[np.int32(np.linspace(0, max_y - 1, nodes))]
    return ((py + crop) / (net_h + crop - 1) * (height - 1))[::-1].astype(np.float64)


def _pred_rows(pred_points: int | str, height: int, y_top: float) -> np.ndarray:
    if pred_points == "rvld":
        rows = rvld_node_rows(height)
        return rows[rows >= y_top]  # height_idx: only the nodes the lane reaches
    return np.linspace(height - 1, y_top, int(pred_points))


def _text(lanes: list[np.ndarray], decimals: int) -> str:
    return "".join(" ".join(f"{v:.{decimals}f}" for v in lane.ravel()) + "\n" for lane in lanes)


def make_workload(
    folder: Path, frames: int, length: int, size: tuple[int, int], pred_points: int | str = "rvld", seed: int = 0
) -> list[str]:
    """Write ``anno/`` and ``pred/`` trees; returns the entries ``<sequence>/<frame>`` in time order."""
    rng = np.random.default_rng(seed)
    entries = []
    for s in range(-(-frames // length)):
        seq = f"{s:03d}_Road_frames"
        (folder / "anno" / seq).mkdir(parents=True)
        (folder / "pred" / seq).mkdir(parents=True)
        n_lanes = int(rng.integers(3, 6))
        vx = size[1] / 2 + rng.normal(0, 80)
        bottoms = np.sort(rng.uniform(-0.2, 1.2, n_lanes)) * size[1]
        bends = rng.normal(0, 60, n_lanes)
        noise = rng.choice([3.0, 8.0, 20.0])
        for f in range(min(length, frames - s * length)):
            bottoms += rng.normal(0, 6, n_lanes)  # the road drifts
            y_top = size[0] * rng.uniform(0.45, 0.55)
            anno = [
                _lane(xb, vx, np.linspace(size[0] - 1, y_top, int(rng.integers(30, 61))), y_top, b)
                for xb, b in zip(bottoms, bends, strict=True)
            ]
            rows = _pred_rows(pred_points, size[0], y_top + 20)
            pred = [
                _lane(xb + rng.normal(0, noise), vx + rng.normal(0, noise), rows, y_top + 20, b)
                for xb, b in zip(bottoms, bends, strict=True)
                if rng.random() > 0.1
            ]
            if rng.random() < 0.1:
                pred.append(_lane(rng.uniform(0, size[1]), vx, rows, y_top + 20, 0.0))
            (folder / "anno" / seq / f"{f:05d}.lines.txt").write_text(_text(anno, 1))
            (folder / "pred" / seq / f"{f:05d}.lines.txt").write_text(_text(pred, 3))
            entries.append(f"{seq}/{f:05d}")
    return entries


def read_sequences(folder: Path, entries: list[str]) -> dict[str, list[Frame]]:
    seqs: dict[str, list[Frame]] = {}
    for e in entries:
        pred = read_culane_lines(folder / "pred" / f"{e}.lines.txt")
        anno = read_culane_lines(folder / "anno" / f"{e}.lines.txt", missing_ok=False)
        seqs.setdefault(e.rsplit("/", 1)[0], []).append(Frame(pred, anno))
    return seqs


# ------------------------------------------------------------------------------------------ reference
def prepare_reference(
    path: Path, folder: Path, entries: list[str], size: tuple[int, int]
) -> Callable[[float], dict[str, float]]:
    """Load RVLD's script unmodified with the I/O glue it needs, write the folders and pickles its
    ``LaneEval_Temporal.settings`` reads, and return ``measure(threshold)``: its ``measure_IoU("test", iou)``."""
    utils = types.ModuleType("libs.utils")

    def save_pickle(path: str, data: object) -> None:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with open(path + ".pickle", "wb") as f:
            pickle.dump(data, f)

    def load_pickle(path: str) -> object:
        with open(path + ".pickle", "rb") as f:
            return pickle.load(f)

    utils.save_pickle, utils.load_pickle = save_pickle, load_pickle
    utils.__all__ = ["save_pickle", "load_pickle"]
    p_tqdm = types.ModuleType("p_tqdm")
    p_tqdm.p_map = p_tqdm.t_map = lambda fn, *its, **kw: list(map(fn, *its))  # in this process: one core
    libs = types.ModuleType("libs")
    libs.utils = utils
    sys.modules.update({"libs": libs, "libs.utils": utils, "p_tqdm": p_tqdm})
    mod = types.ModuleType("evaluate_temporal")
    mod.__file__ = str(path)
    exec(compile(path.read_text(), str(path), "exec"), mod.__dict__)
    out = folder / "rvld" / "out"
    data = folder / "rvld" / "dataset"
    pred_txt = out / "test" / "results" / "iou" / "txt" / "pred_txt"
    for e in entries:
        for src, dst in ((folder / "pred", pred_txt), (folder / "anno", data / "txt" / "anno_txt")):
            (dst / e).parent.mkdir(parents=True, exist_ok=True)
            (dst / f"{e}.lines.txt").write_bytes((src / f"{e}.lines.txt").read_bytes())
    save_pickle(str(out / "test" / "pickle" / "datalist"), entries)
    save_pickle(str(out / "test" / "results" / "iou" / "shape_list"), [(*size, 3)] * len(entries))
    cfg = types.SimpleNamespace(dir={"out": str(out), "dataset": str(data)}, num_t=1)

    def measure(threshold: float) -> dict[str, float]:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            return mod.LaneEval_Temporal(cfg).measure_IoU("test", iou=threshold)

    return measure


# ---------------------------------------------------------------------------------------------- timing
def _median(fn: Callable[[], object], runs: int) -> tuple[float, float, object]:
    """Median wall-clock and CPU seconds of ``runs`` calls (one thread: CPU time is the time on one core, what
    the machine's other jobs do not inflate as much), and the last result."""
    wall, cpu, out = [], [], None
    for _ in range(runs):
        t, c = time.perf_counter(), time.process_time()
        out = fn()
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    return statistics.median(wall), statistics.median(cpu), out


def breakdown(folder: Path, entries: list[str], size: tuple[int, int], runs: int, total_cpu: float) -> dict[str, float]:
    """CPU seconds of each stage of ``temporal.evaluate`` on all frames, each timed alone on the same lanes
    (medians of ``runs``); ``rest`` is the total minus the stages: the IoU of the crops and the matching."""
    frames = [f for seq in read_sequences(folder, entries).values() for f in seq]
    lanes = [lane for f in frames for lane in (*f.preds, *f.target)]
    out: dict[str, float] = {}
    out["read"] = _median(lambda: read_sequences(folder, entries), runs)[1]
    _, out["points"], kept = _median(lambda: temporal._frame_lanes(lanes, "vil100", "a"), runs)
    _, out["splines"], splines = _median(lambda: [temporal._spline(p) for p in kept], runs)
    # the drawings are dropped as they are made, as evaluate drops them frame by frame (kept, they fill GBs)
    out["drawing"] = _median(lambda: [temporal._draw(p, size).area for p in splines], runs)[1]
    # OpenCV's share of it: the same polylines calls on canvases of the same sizes (views of one buffer)
    calls = []
    for p in splines:
        d = temporal._draw(p, size)
        if d.area:
            calls.append((d.mask.shape, (p - np.array([d.x0, d.y0], p.dtype)).reshape(-1, 1, 2)))
    buffer = np.zeros((max(s[0] for s, _ in calls), max(s[1] for s, _ in calls)), np.uint8)
    width = temporal.LANE_WIDTH

    def polylines() -> None:
        for (h, w), q in calls:
            cv2.polylines(buffer[:h, :w], [q], False, 1, thickness=width)

    out["opencv_polylines"] = _median(polylines, runs)[1]
    out["rest"] = total_cpu - out["read"] - out["points"] - out["splines"] - out["drawing"]
    out["floor"] = out["read"] + out["splines"] + out["opencv_polylines"]
    return out


def _pred_points(text: str) -> int | str:
    if text == "rvld":
        return text
    if not text.isdigit() or int(text) < 2:
        raise argparse.ArgumentTypeError(f"expected 'rvld' or a number of points >= 2, got {text!r}")
    return int(text)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=10_000)
    ap.add_argument("--sequence-length", type=int, default=100, help="frames per sequence (VIL-100: 100)")
    ap.add_argument("--size", default=VIL100_SIZE, help="frame WxH")
    ap.add_argument(
        "--pred-points",
        type=_pred_points,
        default="rvld",
        help="points of a predicted lane: 'rvld' (RVLD's node rows within the lane, default) or a number N",
    )
    ap.add_argument("--runs", type=int, default=3, help="runs per measurement (median reported)")
    ap.add_argument(
        "--jobs",
        type=int,
        default=1,
        help="also time stamlane-eval with its sequences in N processes (0: one per core)",
    )
    ap.add_argument("--reference", type=Path, help="a copy of RVLD's VIL-100 evaluate_temporal.py")
    ap.add_argument("--reference-frames", type=int, default=100, help="frames the (slow) reference scores")
    ap.add_argument("--out", type=Path, default=Path("outputs/bench/video_speed.json"), help="figures as JSON")
    args = ap.parse_args(argv)

    if (refused := guard_out("video_speed.py", args.out)) is not None:  # before any work
        return refused
    cv2.setNumThreads(1)  # one core: OpenCV would otherwise spread some calls over the machine's cores
    gc.disable()  # as `stamlane-eval` runs (cli.main): the collector would only walk the parsed lanes
    w, h = (int(v) for v in args.size.lower().split("x"))
    size = (h, w)
    if args.reference is not None and not args.reference.is_file():
        return fail("video_speed", f"{args.reference}: no such file")
    results: dict[str, object] = {"frames": args.frames, "size": args.size, "pred_points": args.pred_points}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        print(f"generating {args.frames} frames ...", file=sys.stderr)
        entries = make_workload(folder, args.frames, args.sequence_length, size, args.pred_points)

        def ours(subset: list[str]) -> temporal.TemporalResult:
            return temporal.evaluate(read_sequences(folder, subset), (0.5,), size=size)

        ours(entries[:2])  # imports scipy
        t_all, cpu_all, res = _median(lambda: ours(entries), args.runs)
        c = res.totals[0.5]
        results |= {"seconds": t_all, "cpu_seconds": cpu_all, "pairs": res.pairs, "Ns": c.ns, "Nj": c.nj, "Nm": c.nm}
        print(
            f"stamlane-eval temporal @0.5, {args.frames} frames ({res.sequences} sequences, {res.pairs} pairs, "
            f"{size[1]}x{size[0]}), read + score: {t_all:.2f} s wall, {cpu_all:.2f} s CPU "
            f"({1e3 * cpu_all / args.frames:.2f} ms a frame); Ns {c.ns} Nj {c.nj} Nm {c.nm}, Rs {c.rs:.4f}"
        )
        if args.jobs != 1:
            jobs = args.jobs or os.cpu_count() or 1

            def spread() -> temporal.TemporalResult:
                return temporal.evaluate(read_sequences(folder, entries), (0.5,), size=size, jobs=jobs)

            t_jobs, _, res_jobs = _median(spread, args.runs)
            results |= {"jobs": jobs, "jobs_seconds": t_jobs, "jobs_same_numbers": res_jobs.as_dict() == res.as_dict()}
            print(
                f"the same in {jobs} processes (--jobs {jobs}), reading in this one: {t_all / t_jobs:.2f}x, "
                f"{t_jobs:.2f} s wall; numbers {'equal' if res_jobs.as_dict() == res.as_dict() else 'DIFFERENT'}"
            )
        stages = breakdown(folder, entries, size, args.runs, cpu_all)
        results["stages_cpu_s"] = stages
        print(
            "stages, CPU s (each alone, same lanes): "
            + ", ".join(f"{k} {v:.2f}" for k, v in stages.items() if k != "floor")
            + f"; floor (reading + splines + OpenCV's drawing): {stages['floor']:.2f} s"
        )
        if args.reference is not None:
            subset = entries[: args.reference_frames]
            t_sub, cpu_sub, mine = _median(lambda: ours(subset), args.runs)
            print(f"RVLD's script on the first {len(subset)} frames ...", file=sys.stderr)
            measure = prepare_reference(args.reference, folder, subset, size)
            t_ref, cpu_ref, ref = _median(lambda: measure(0.5), 1)
            m = mine.totals[0.5]
            same = (ref["Ns"], ref["Nj"], ref["Nm"], ref["Rs"]) == (m.ns, m.nj, m.nm, m.rs)
            results |= {
                "reference_frames": len(subset),
                "reference_s": t_ref,
                "reference_cpu_s": cpu_ref,
                "ours_on_reference_frames_s": t_sub,
                "ours_on_reference_frames_cpu_s": cpu_sub,
                "ratio_cpu": cpu_ref / cpu_sub,
                "same_numbers": same,
            }
            print(
                f"first {len(subset)} frames, CPU time: RVLD's evaluate_temporal.py {cpu_ref:.2f} s, stamlane-eval "
                f"{cpu_sub:.3f} s: {cpu_ref / cpu_sub:.0f}x (wall {t_ref:.2f} s and {t_sub:.3f} s); numbers "
                f"{'equal' if same else 'DIFFERENT'} (RVLD Ns {ref['Ns']} Nj {ref['Nj']} Nm {ref['Nm']} Rs {ref['Rs']}; "
                f"stamlane-eval {m.ns} {m.nj} {m.nm} {m.rs})"
            )
    write_result(args.out, results | machine())  # after the timings: machine() imports torch
    return 0


if __name__ == "__main__":
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    sys.exit(main())
