"""``stamlane-eval``: the command line of the evaluators.

    stamlane-eval tusimple PRED GT [--json] [--per-image FILE]
    stamlane-eval culane PRED_DIR GT_DIR [--list LIST] [--iou 0.3 0.5] [--width 30] [--size 1640x590]
                         [--variant official|lanedet] [--json] [--per-image FILE]
    stamlane-eval apollo PRED_DIR GT_DIR ...     (the culane command with ApolloScape's 3384x2710)
    stamlane-eval video PRED_DIR GT_DIR [--list LIST] [--iou 0.5 0.8] [--match-iou 0.5] [--width 30] [--size WxH]
                        [--jobs N] [--json] [--per-sequence FILE]
    stamlane-eval video PRED.json GT.json ...    (TuSimple json-lines, or folders of them; sequence: raw_file's folder)
    stamlane-eval video PRED_DIR GT_DIR --temporal [--protocol vil100|openlane-v] [--list LIST] [--iou 0.5 0.8]
                        [--size WxH] [--sizes FILE] [--jobs N] [--json] [--per-sequence FILE]   (RVLD's Rs/Rj/Rm)

Bad input: one line on stderr naming the file and the problem, exit status 2, no traceback.
"""

from __future__ import annotations

import argparse
import gc
import json
import sys
import warnings
from collections.abc import Sequence
from concurrent.futures import BrokenExecutor
from pathlib import Path

import stamlane_eval
from stamlane_eval import culane, temporal, tusimple, video
from stamlane_eval.cli_tools import (
    OneLineParser,
    OutputError,
    check_outputs,
    format_wxh,
    parse_or_status,
    parse_wxh,
)
from stamlane_eval.io import (
    MAX_IMAGE_SIDE,
    MAX_LANE_WIDTH,
    LaneFileError,
    cpp_tool_text,
    culane_entries,
    images_beside,
    lane_py_line,
    read_culane_folders,
    read_tusimple,
    read_video,
    tusimple_lanes_by_image,
    write_jsonl,
)
from stamlane_eval.io.files import (
    path_problem,
)

__all__ = ["main"]

EXIT_BAD_INPUT = 2
MAX_JOBS = 256  # --jobs: each worker is a whole interpreter with numpy, scipy and OpenCV (~100 MB); more is no gain
MAX_THRESHOLDS = 100  # --iou: distinct thresholds (a sweep in steps of 0.01); each one is counted for every image
PROGRESS_MIN_ITEMS = 200  # images or frames: below it a run is short and needs no bar
SWAP_SAMPLE = 16  # list entries looked at (evenly spread) for images beside their .lines.txt: 2 x 16 stat calls


def _size(text: str) -> tuple[int, int]:
    return parse_wxh(text, MAX_IMAGE_SIDE)  # (H, W)


def _lane_width(text: str) -> int:
    width = _positive_int(text)
    if width > MAX_LANE_WIDTH:
        raise argparse.ArgumentTypeError(f"expected a lane width of at most {MAX_LANE_WIDTH} px, got {text!r}")
    return width


def _iou(text: str) -> float:
    try:
        t = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an IoU threshold in [0, 1), got {text!r}") from None
    if not 0.0 <= t < 1.0:
        raise argparse.ArgumentTypeError(f"expected an IoU threshold in [0, 1), got {text!r}")
    return t


def _positive_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if v <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return v


def _jobs(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        v = -1
    if not 0 <= v <= MAX_JOBS:
        raise argparse.ArgumentTypeError(
            f"expected a number of processes in 0..{MAX_JOBS} (0: one per core), got {text!r}"
        )
    return v


def _output_format(parser: argparse.ArgumentParser, official: str | None) -> None:
    """``--format table|json[|official]`` and its alias ``--json``."""
    choices = ("table", "json", "official") if official else ("table", "json")
    what = f"; official: {official}" if official else ""
    parser.add_argument(
        "--format", choices=choices, default="table", help=f"table: percent, as papers report; json: one object{what}"
    )
    parser.add_argument("--json", dest="format", action="store_const", const="json", help="the same as --format json")


class _Version(argparse.Action):
    """``--version``, reading the version only when asked (see ``stamlane_eval.__getattr__``)."""

    def __call__(self, parser: argparse.ArgumentParser, *args: object) -> None:
        print(f"stamlane-eval {stamlane_eval.__version__}")
        parser.exit()


def _build_parser() -> OneLineParser:
    parser = OneLineParser(
        prog="stamlane-eval", description="Lane metrics equal to the official tools, number for number."
    )
    parser.add_argument("--version", action=_Version, nargs=0, help="show the version and exit")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=OneLineParser)

    ts = sub.add_parser("tusimple", help="TuSimple accuracy / FP / FN (official lane.py) and the paper's F1")
    ts.add_argument("pred", type=Path, help="predictions, json-lines: raw_file, lanes, run_time")
    ts.add_argument("gt", type=Path, help="ground truth, json-lines: raw_file, lanes, h_samples")
    _output_format(ts, official="the JSON line lane.py prints")
    ts.add_argument("--per-image", type=Path, metavar="FILE", help="write per-image results as json-lines")
    ts.add_argument(
        "--no-time-limit",
        dest="time_limit",
        action="store_false",
        help="do not score images whose run_time exceeds 200 ms as missed (the benchmark does; for comparing "
        "models timed on a busy machine)",
    )

    for name, size in (("culane", culane.CULANE_SIZE), ("apollo", culane.APOLLO_SIZE)):
        cu = sub.add_parser(name, help=f"{name} area metric (official C++ tool or lanedet), default {format_wxh(size)}")
        cu.add_argument("pred", type=Path, help="folder of predicted .lines.txt (or a TuSimple json-lines file)")
        cu.add_argument("gt", type=Path, help="folder of annotated .lines.txt (or a TuSimple json-lines file)")
        cu.add_argument("--list", type=Path, help="image list (CULane style); default: every .lines.txt in GT")
        cu.add_argument("--iou", type=_iou, nargs="+", default=list(culane.IOU_THRESHOLDS), help="IoU thresholds")
        cu.add_argument("--width", type=_lane_width, default=culane.LANE_WIDTH, help="lane line width in pixels")
        cu.add_argument("--size", type=_size, default=None, help=f"image WxH (default {format_wxh(size)})")
        cu.add_argument("--variant", choices=culane.VARIANTS, default="official", help="official C++ or lanedet")
        _output_format(cu, official="what the C++ tool writes to its -o file, per IoU threshold")
        cu.add_argument("--per-image", type=Path, metavar="FILE", help="write per-image results as json-lines")
        cu.add_argument(
            "--as-given",
            action="store_true",
            help="score PRED and GT in the order given even where they look swapped (images beside PRED's "
            ".lines.txt and none beside GT's; TuSimple files: run_time in GT and not in PRED)",
        )
        cu.set_defaults(default_size=size)

    vd = sub.add_parser(
        "video", help="video metrics: mIoU, F@0.5/0.8 (MMA-Net), identity switches, flicker; --temporal: Rs/Rj/Rm"
    )
    vd.add_argument(
        "pred",
        type=Path,
        help="folder of predictions, <sequence>/<frame>.lines.txt, or TuSimple json-lines (stamlane predict's "
        "predictions.json; sequence: the folder of raw_file)",
    )
    vd.add_argument(
        "gt",
        type=Path,
        help="VIL-100 root (Json/<video>/<frame>.jpg.json), <sequence>/<frame>.lines.txt, or TuSimple records: a "
        "json-lines file or a folder of .json files (frame_labels/)",
    )
    vd.add_argument(
        "--list", type=Path, help="frames in time order, <sequence>/<frame> per line; default: every frame, by name"
    )
    vd.add_argument("--iou", type=_iou, nargs="+", default=list(video.VIDEO_IOU_THRESHOLDS), help="IoU thresholds")
    vd.add_argument(
        "--match-iou", type=_iou, default=None, help=f"IoU of a match for switches/flicker ({video.MATCH_IOU})"
    )
    vd.add_argument("--width", type=_lane_width, default=None, help=f"lane line width in pixels ({culane.LANE_WIDTH})")
    vd.add_argument("--size", type=_size, default=None, help="image WxH (default: VIL-100 json info)")
    vd.add_argument(
        "--sizes",
        type=Path,
        metavar="FILE",
        help='JSON {"<sequence>": "WxH", "<sequence>/<frame>": "WxH", ...}: sizes that differ between videos',
    )
    vd.add_argument(
        "--temporal",
        action="store_true",
        help="RVLD's temporal stability instead: Ns, Nj, Nm, Rs, Rj, Rm per threshold (evaluate_temporal.py)",
    )
    vd.add_argument(
        "--protocol",
        choices=temporal.PROTOCOLS,
        default="vil100",
        help="with --temporal: which copy of RVLD's script (openlane-v: 1920x1280 lanes drawn at 960x640)",
    )
    vd.add_argument(
        "--jobs",
        type=_jobs,
        default=1,
        metavar="N",
        help="score the sequences in N processes (0: one per core; default 1); the numbers do not change",
    )
    _output_format(vd, official=None)
    vd.add_argument("--per-sequence", type=Path, metavar="FILE", help="write per-sequence results as json-lines")
    vd.add_argument(
        "--as-given",
        action="store_true",
        help="score TuSimple PRED and GT in the order given even where they look swapped (run_time in GT, not PRED)",
    )

    return parser


def _table(rows: Sequence[Sequence[object]]) -> str:
    cells = [[f"{v:.4f}" if isinstance(v, float) else str(v) for v in row] for row in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(cells[0]))]
    lines = ["  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True)) for r in cells]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


def _inputs(args: argparse.Namespace) -> list[Path | None]:
    """Every path a command reads: predictions, ground truth, the list and sizes files."""
    return [args.pred, args.gt, getattr(args, "list", None), getattr(args, "sizes", None)]


def _outputs(args: argparse.Namespace) -> list[Path | None]:
    """Every path a command writes (besides stdout)."""
    return [getattr(args, "per_image", None), getattr(args, "per_sequence", None)]


def _timed(records: Sequence[dict[str, object]]) -> bool:
    """Whether any record carries ``run_time``: every prediction does (lane.py requires it), a label never."""
    return any("run_time" in r for r in records)


def _swapped_tusimple(
    args: argparse.Namespace, preds: Sequence[dict[str, object]], gts: Sequence[dict[str, object]]
) -> str | None:
    """Why PRED and GT look given in the wrong order, or None: no record of PRED has a ``run_time`` (every
    prediction needs one) while GT's records have one."""
    if _timed(preds) or not _timed(gts):
        return None
    return (
        f"{args.pred} has no run_time (a label file?) and {args.gt} has one (a prediction file?): the files look "
        f"swapped; the order is stamlane-eval {args.command} PRED GT"
    )


def _run_tusimple(args: argparse.Namespace) -> int:
    preds = read_tusimple(args.pred)
    gts = read_tusimple(args.gt)
    swapped = _swapped_tusimple(args, preds, gts)
    if swapped:  # never a valid input: a prediction without run_time is refused by lane.py's check anyway
        raise LaneFileError(swapped)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            res = tusimple.evaluate(preds, gts, time_limit=args.time_limit)
            tusimple.check_rates(res)
    except tusimple.TuSimpleInputError as e:
        where = {"pred": args.pred, "gt": args.gt}.get(e.source or "", f"{args.pred} / {args.gt}")
        line = f": line {e.line}" if e.line is not None else ""
        raise LaneFileError(f"{where}{line}: {e.message}") from None
    said = [str(w.message) for w in caught]
    if args.time_limit and res.late_images:
        said.append(tusimple.late_message(res.late_images, res.images, "--no-time-limit"))
    if said:  # at most one warning line, whatever there is to say
        print(f"stamlane-eval: warning: {args.pred}: {'; '.join(said)}", file=sys.stderr)
    if args.per_image:
        write_jsonl(
            args.per_image,
            [
                {
                    "raw_file": p["raw_file"],
                    "acc": r.acc,
                    "fp": r.fp,
                    "fn": r.fn,
                    "matched": r.matched,
                    "n_pred": r.n_pred,
                    "n_gt": r.n_gt,
                }
                for p, r in zip(preds, res.per_image, strict=True)
            ],
            _inputs(args),
        )
    if args.format == "json":
        print(json.dumps(res.as_dict()))
    elif args.format == "official":
        print(lane_py_line(res.accuracy, res.fp, res.fn))
    else:
        pct = [f"{100 * v:.2f}" for v in (res.accuracy, res.fp, res.fn, res.f1)]
        print(_table([["images", "accuracy %", "FP %", "FN %", "F1 % (paper)"], [res.images, *pct]]))
        print(
            f"lane counts (not the paper's F1): TP {res.lane_tp}  FP {res.lane_fp}  FN {res.lane_fn}  "
            f"precision {100 * res.lane_precision:.2f} %  recall {100 * res.lane_recall:.2f} %  "
            f"F1 {100 * res.lane_f1:.2f} %"
        )
    return 0


def _run_culane(args: argparse.Namespace) -> int:
    size = args.size or args.default_size
    if args.pred.suffix == ".json" or args.gt.suffix == ".json":
        if args.size is None:
            raise LaneFileError(f"{args.gt}: TuSimple-format files need --size WxH (TuSimple images are 1280x720)")
        gt_records, pred_records = read_tusimple(args.gt), read_tusimple(args.pred)
        swapped = None if args.as_given else _swapped_tusimple(args, pred_records, gt_records)
        if swapped:
            raise LaneFileError(f"{swapped} (--as-given scores them as given)")
        entries, preds, gts = tusimple_lanes_by_image(pred_records, gt_records, args.pred, args.gt)
    else:
        if not args.pred.is_dir():
            raise LaneFileError(f"{args.pred}: not a directory")
        entries = culane_entries(args.gt, args.list)
        if not args.as_given:
            _refuse_swapped_folders(args, entries)
        preds, gts = read_culane_folders(args.pred, args.gt, entries)  # nothing read outside the folders given
    thresholds = sorted(set(args.iou))
    try:
        res = culane.evaluate(
            preds,
            gts,
            thresholds,
            args.width,
            size,
            args.variant,
            progress=sys.stderr.isatty() and len(gts) > PROGRESS_MIN_ITEMS,
            names=entries,
        )
    except ValueError as e:
        raise LaneFileError(f"{args.pred}: {e}") from None
    if args.format != "official":  # the C++ tool's own text writes its -1 and -nan (see io.cpp_tool_text)
        _refuse_zero_denominators(res, args)
    if args.per_image:
        recs = []
        for entry, r in zip(entries, res.per_image, strict=True):
            rec: dict[str, object] = {"entry": entry, "n_pred": r.n_pred, "n_gt": r.n_gt}
            rec.update({str(t): list(r.counts[t]) for t in thresholds})
            rec["matched_iou"] = [float(v) for v in r.matched_iou]
            recs.append(rec)
        write_jsonl(args.per_image, recs, _inputs(args))
    if args.format == "json":
        print(json.dumps(res.as_dict()))
    elif args.format == "official":
        print("\n".join(cpp_tool_text(c.tp, c.fp, c.fn) for c in res.totals.values()), end="")
    else:
        rows: list[list[object]] = [["IoU", "TP", "FP", "FN", "precision %", "recall %", "F1 %"]]
        for t, c in res.totals.items():
            rows.append([f"{t:g}", c.tp, c.fp, c.fn, *(f"{100 * v:.2f}" for v in (c.precision, c.recall, c.f1))])
        print(f"{args.command} ({args.variant}), {res.images} images, {format_wxh(size)}, width {args.width}")
        print(_table(rows))
    return 0


def _refuse_swapped_folders(args: argparse.Namespace, entries: Sequence[str]) -> None:
    """Refuse folders that look given in the wrong order (P and R would be exchanged, silently): the images lie
    beside the ``.lines.txt`` of PRED, as in a CULane dataset root, and beside none of GT's. Looked at on
    ``SWAP_SAMPLE`` entries spread over the list; a prediction folder holds no images (``stamlane predict``
    writes its overlays elsewhere).

    Raises:
        LaneFileError: naming both folders, the order and ``--as-given``.
    """
    sample = list(entries[:: max(1, len(entries) // SWAP_SAMPLE)][:SWAP_SAMPLE])
    in_pred = images_beside(args.pred, sample)
    if 2 * in_pred < len(sample) or images_beside(args.gt, sample):
        return
    raise LaneFileError(
        f"{args.pred} holds the images beside its .lines.txt ({in_pred} of {len(sample)} looked at), as a dataset "
        f"root does, and {args.gt} none: the folders look swapped; the order is stamlane-eval {args.command} "
        f"PRED_DIR GT_DIR (--as-given scores them as given)"
    )


def _refuse_zero_denominators(res: culane.CULaneResult, args: argparse.Namespace) -> None:
    """Precision or recall 0/0 (no predicted lane, or no annotated lane, in any image): the C++ tool prints -1
    there, which is no rate; refused as a table or json (docs/evaluators.md, "What is scored and what is
    refused"), written as the C++ tool writes it with ``--format official``."""
    c = next(iter(res.totals.values()))  # tp + fp and tp + fn are the same at every threshold
    if c.tp + c.fp == 0:
        raise LaneFileError(
            f"{args.pred}: no predicted lane in any of the {res.images} images: precision is 0/0 (the C++ tool "
            f"prints -1)"
        )
    if c.tp + c.fn == 0:
        raise LaneFileError(
            f"{args.gt}: no annotated lane in any of the {res.images} images: recall is 0/0 (the C++ tool prints -1)"
        )


def _read_video(args: argparse.Namespace, need_size: bool) -> dict[str, list[video.Frame]]:
    """The frames of ``args.gt`` (or of ``--list``) with their predictions (`stamlane_eval.io.read_video`); one
    warning line when no frame has a prediction at all."""
    found = read_video(
        args.pred,
        args.gt,
        list_file=args.list,
        sizes=args.sizes,
        size=args.size,
        need_size=need_size,
        as_given=args.as_given,
    )
    if not found.predicted:  # every frame scored as missed: most likely a wrong folder or layout, not a model
        where = "a record" if found.tusimple_pred else f"a file {args.pred}/<sequence>/<frame>.lines.txt"
        print(
            f"stamlane-eval: warning: {args.pred}: no prediction for any of the {found.frames} "
            f"frames (expected {where} per frame of {args.gt}); every frame scores as without lanes",
            file=sys.stderr,
        )
    return found.sequences


def _show_progress(sequences: dict[str, list[video.Frame]]) -> bool:
    """A progress bar on a terminal, for more than 200 frames (as for more than 200 CULane images)."""
    return sys.stderr.isatty() and sum(len(f) for f in sequences.values()) > PROGRESS_MIN_ITEMS


def _run_video(args: argparse.Namespace) -> int:
    if args.temporal:
        return _run_temporal(args)
    sequences = _read_video(args, need_size=True)
    thresholds = sorted(set(args.iou))
    width = args.width or culane.LANE_WIDTH
    match_iou = video.MATCH_IOU if args.match_iou is None else args.match_iou
    try:
        res = video.evaluate(
            sequences, thresholds, match_iou, width, progress=_show_progress(sequences), jobs=args.jobs
        )
    except ValueError as e:
        raise LaneFileError(f"{args.gt}: {e}") from None
    if args.per_sequence:
        write_jsonl(args.per_sequence, [s.as_dict() for s in res.per_sequence], _inputs(args))
    if args.format == "json":
        print(json.dumps(res.as_dict()))
    else:
        print(f"video, {res.sequences} sequences, {res.frames} frames, width {width}")
        rows: list[list[object]] = [["IoU", "TP", "FP", "FN", "precision", "recall", "F"]]
        for t, c in res.totals.items():
            rows.append([f"{t:g}", c.tp, c.fp, c.fn, c.precision, c.recall, c.f1])
        print(_table(rows))
        print(
            f"mIoU {res.miou:.4f}  identity switches {res.id_switches} (rate {res.switch_rate:.4f})  "
            f"flicker {res.flickers} (rate {res.flicker_rate:.4f})"
        )
    return 0


def _run_temporal(args: argparse.Namespace) -> int:
    for option, flag in (("width", "--width"), ("match_iou", "--match-iou")):
        if getattr(args, option) is not None:
            raise LaneFileError(f"{flag} does not apply to --temporal (RVLD's script draws 30 px and pairs above 0.5)")
    if args.protocol == "openlane-v" and (args.size is not None or args.sizes is not None):
        raise LaneFileError("--size does not apply to --protocol openlane-v (1920x1280 lanes, drawn at 960x640)")
    sequences = _read_video(args, need_size=args.protocol == "vil100")
    if args.protocol == "openlane-v":  # a VIL-100 json's own size does not apply either
        sequences = {k: [video.Frame(f.preds, f.target) for f in v] for k, v in sequences.items()}
    thresholds = sorted(set(args.iou))
    try:
        res = temporal.evaluate(
            sequences, thresholds, protocol=args.protocol, progress=_show_progress(sequences), jobs=args.jobs
        )
    except ValueError as e:
        raise LaneFileError(f"{args.gt}: {e}") from None
    if not res.totals[thresholds[0]].total:
        raise LaneFileError(
            f"{args.gt}: no annotated lane is matched between two consecutive frames ({res.pairs} pairs of frames): "
            f"Rs, Rj, Rm are 0/0 (RVLD's script fails here with ZeroDivisionError)"
        )
    if args.per_sequence:
        write_jsonl(args.per_sequence, [s.as_dict() for s in res.per_sequence], _inputs(args))
    if args.format == "json":
        print(json.dumps(res.as_dict()))
    else:
        n = res.totals[thresholds[0]].total
        print(
            f"temporal stability (RVLD, {args.protocol}), {res.sequences} sequences, {res.frames} frames, "
            f"{res.pairs} pairs of frames, {n} annotated lanes matched across a pair"
        )
        rows: list[list[object]] = [["IoU", "Ns", "Nj", "Nm", "Rs %", "Rj %", "Rm %"]]
        for t, c in res.totals.items():
            rows.append([f"{t:g}", c.ns, c.nj, c.nm, *(f"{100 * v:.2f}" for v in (c.rs, c.rj, c.rm))])
        print(_table(rows))
    return 0


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the exit status (0 ok, 2 bad input)."""
    gc.disable()  # a short run that builds no cycles: the collector would only walk the parsed files (-30 % time)
    try:
        return _main(argv)
    finally:
        gc.enable()


def _main(argv: list[str] | None) -> int:
    args = parse_or_status(_build_parser(), argv)
    if isinstance(args, int):  # --help, --version, or a usage error already printed in one line
        return args
    try:
        for arg in sys.argv[1:] if argv is None else argv:  # the door: what can be no path is one line, not a trace
            problem = path_problem(arg.split("=", 1)[1] if arg.startswith("-") and "=" in arg else arg)
            if problem is not None:
                raise LaneFileError(f"argument {arg.encode('utf-8', 'backslashreplace').decode()!r:.300} {problem}")
        check_outputs(_outputs(args), _inputs(args), files=True)  # every output against every input, before any read
        if len(set(getattr(args, "iou", ()))) > MAX_THRESHOLDS:
            raise LaneFileError(f"--iou: {len(set(args.iou))} thresholds, more than the limit of {MAX_THRESHOLDS}")
        if args.command == "tusimple":
            return _run_tusimple(args)
        if args.command in ("culane", "apollo"):
            return _run_culane(args)
        return _run_video(args)
    except (OutputError, LaneFileError) as e:
        print(f"stamlane-eval: error: {e}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except BrokenExecutor as e:  # a --jobs worker killed (out of memory, a signal): no result to give
        print(
            f"stamlane-eval: error: a worker process of --jobs {getattr(args, 'jobs', '')} died ({e})", file=sys.stderr
        )
        return EXIT_BAD_INPUT


if __name__ == "__main__":
    sys.exit(main())
