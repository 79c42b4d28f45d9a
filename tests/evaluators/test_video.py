"""Video metrics on hand-made sequences with known answers, and the ``stamlane-eval video`` command."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from stamlane_eval import video
from stamlane_eval.cli import main
from stamlane_eval.video import Frame

SIZE = (360, 640)  # (H, W)
A = np.array([[100.0, 359.0], [180.0, 250.0], [260.0, 150.0]])
B = np.array([[540.0, 359.0], [460.0, 250.0], [380.0, 150.0]])
FAR = np.array([[320.0, 100.0], [330.0, 0.0]])  # overlaps neither A nor B: IoU 0


def _frame(preds: list[np.ndarray], target: list[np.ndarray], **kw: object) -> Frame:
    return Frame(preds, target, size=SIZE, **kw)


def test_perfect_sequence() -> None:
    res = video.evaluate({"s": [_frame([A, B], [A, B])] * 3})
    assert res.miou == 1.0
    assert res.totals[0.5].f1 == 1.0 and res.totals[0.8].tp == 6
    assert (res.id_switches, res.switch_rate, res.flickers, res.flicker_rate) == (0, 0.0, 0, 0.0)
    assert res.per_sequence[0].switch_chances == 4 and res.per_sequence[0].flicker_chances == 2


def test_identity_switches() -> None:
    # the model lists the lanes in another order in frame 1: both annotated lanes change predicted identity
    # between frames 0->1 and again 1->2: 4 switches out of 4 chances
    res = video.evaluate({"s": [_frame([A, B], [A, B]), _frame([B, A], [A, B]), _frame([A, B], [A, B])]})
    assert (res.id_switches, res.switch_rate) == (4, 1.0)
    assert res.totals[0.5].f1 == 1.0  # frame-level numbers do not see it
    # explicit ids that follow the lanes: no switch
    ids = [_frame([A, B], [A, B], pred_ids=[7, 8]), _frame([B, A], [A, B], pred_ids=[8, 7])]
    assert video.evaluate({"s": ids}).id_switches == 0


def test_flicker_and_counts() -> None:
    frames = [_frame([A, B], [A, B]), _frame([B], [A, B]), _frame([A, B], [A, B]), _frame([A, B], [A, B])]
    res = video.evaluate({"s": frames})
    # lane A matched in frames 0 and 2, missed in 1: one flicker; chances: frame 1 (A and B, both matched in
    # frames 0 and 2) and frame 2 (B only: A is not matched in frame 1)
    assert (res.flickers, res.per_sequence[0].flicker_chances) == (1, 3)
    assert res.flicker_rate == 1 / 3
    c = res.totals[0.5]
    assert (c.tp, c.fp, c.fn) == (7, 0, 1)
    # the lone B in frame 1 is predicted lane 0 there but 1 elsewhere: 2 switches
    assert res.id_switches == 2


def test_miou_per_frame_over_predictions_then_sequences() -> None:
    # frame mIoU: matched IoUs summed over the predicted lanes' count (unmatched -> 0): [1.0, 0.5] -> 0.75
    seqs = {
        "one": [_frame([A], [A]), _frame([A, FAR], [A])],
        "two": [_frame([B], [B])],
        "empty": [_frame([], [])],  # MMA-Net's counter.cpp: a frame with neither lanes nor predictions scores 1
    }
    res = video.evaluate(seqs)
    assert [s.miou for s in res.per_sequence] == [0.75, 1.0, 1.0]
    assert res.miou == (0.75 + 1.0 + 1.0) / 3  # over sequences, not the frame mean 0.875
    assert video.evaluate({"s": [_frame([], [A])]}).miou == 0.0  # annotations, no prediction: 0
    assert video.evaluate({"s": [_frame([A], [])]}).miou == 0.0  # predictions, no annotation: 0
    assert res.sequences == 3 and res.frames == 4


def test_dataset_miou_from_printed_sequence_values() -> None:
    # evaluate.cpp prints each video's mIoU with 6 significant digits; evaluate_iou.py averages the printed text
    assert video.dataset_miou([2 / 3, 1 / 3]) == (0.666667 + 0.333333) / 2
    assert video.dataset_miou([]) == 0.0


def test_lane_absent_in_middle_frame_is_no_flicker() -> None:
    frames = [
        _frame([A, B], [A, B], target_ids=[1, 2]),
        _frame([B], [B], target_ids=[2]),
        _frame([A, B], [A, B], target_ids=[1, 2]),
    ]
    res = video.evaluate({"s": frames})
    assert res.flickers == 0 and res.per_sequence[0].flicker_chances == 1


def test_bad_ids() -> None:
    with pytest.raises(ValueError, match="duplicate"):
        video.evaluate({"s": [_frame([A, B], [A, B], target_ids=[1, 1])]})
    with pytest.raises(ValueError, match="ids for"):
        video.evaluate({"s": [_frame([A, B], [A, B], pred_ids=[1])]})
    with pytest.raises(ValueError, match="no sequence"):
        video.evaluate({})


def _lines(lanes: list[np.ndarray]) -> str:
    return "".join(" ".join(f"{x} {y}" for x, y in lane) + "\n" for lane in lanes)


def _vil_tree(tmp_path: Path) -> tuple[Path, Path]:
    gt, pred = tmp_path / "vil", tmp_path / "pred"
    order = [[A, B], [B, A], [A, B]]
    for f, lanes in enumerate(order):
        ann = {
            "info": {"width": SIZE[1], "height": SIZE[0], "image_path": f"{f:05d}.jpg"},
            "annotations": {"lane": [{"lane_id": 1, "points": A.tolist()}, {"lane_id": 2, "points": B.tolist()}]},
        }
        (gt / "Json" / "0_road").mkdir(parents=True, exist_ok=True)
        (gt / "Json" / "0_road" / f"{f:05d}.jpg.json").write_text(json.dumps(ann))
        (pred / "0_road").mkdir(parents=True, exist_ok=True)
        (pred / "0_road" / f"{f:05d}.lines.txt").write_text(_lines(lanes))
    return pred, gt


def test_cli_vil100_layout(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    pred, gt = _vil_tree(tmp_path)
    assert main(["video", str(pred), str(gt), "--json", "--per-sequence", str(tmp_path / "seq.jsonl")]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["miou"] == 1.0 and res["0.5"]["f1"] == 1.0 and res["0.8"]["tp"] == 6
    assert (res["id_switches"], res["switch_rate"], res["flickers"]) == (4, 1.0, 0)
    assert json.loads((tmp_path / "seq.jsonl").read_text())["sequence"] == "0_road"
    (pred / "0_road" / "00001.lines.txt").unlink()  # missing prediction: no lanes in that frame
    assert main(["video", str(pred), str(gt)]) == 0
    out = capsys.readouterr().out
    assert "flicker 2 (rate 1.0000)" in out and "identity switches 0" in out


def test_cli_lines_layout_and_errors(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    gt, pred = tmp_path / "gt" / "seq", tmp_path / "pred" / "seq"
    gt.mkdir(parents=True)
    pred.mkdir(parents=True)
    for f in range(2):
        (gt / f"{f}.lines.txt").write_text(_lines([A]))
        (pred / f"{f}.lines.txt").write_text(_lines([A]))
    code = main(["video", str(pred.parent), str(gt.parent)])
    err = capsys.readouterr().err
    assert code == 2 and "--size" in err and len(err.strip().splitlines()) == 1
    assert main(["video", str(pred.parent), str(gt.parent), "--size", "640x360", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["0.5"]["tp"] == 2
    bad = tmp_path / "bad"
    (bad / "Json" / "v").mkdir(parents=True)
    (bad / "Json" / "v" / "0.jpg.json").write_text('{"annotations": {}}')
    code = main(["video", str(pred.parent), str(bad)])
    err = capsys.readouterr().err
    assert code == 2 and "annotations.lane" in err and "0.jpg.json" in err


# --------------------------------------------------------------------------- parity with MMA-Net's evaluation
GOLDEN_T = Path(__file__).parent / "golden" / "temporal"
MMA = json.loads((GOLDEN_T / "expected.json").read_text())["mma_net"]


def _golden_first_frame_sizes() -> dict[str, list[Frame]]:
    """The golden temporal set as MMA-Net scores it: every frame of a video at its first frame's size."""
    from stamlane_eval.io import read_culane_lines

    sizes = json.loads((GOLDEN_T / "sizes.json").read_text())
    seqs: dict[str, list[Frame]] = {}
    for entry in (GOLDEN_T / "list.txt").read_text().split():
        seq = entry.rsplit("/", 1)[0]
        size = seqs[seq][0].size if seq in seqs else tuple(sizes[entry])
        pred = read_culane_lines(GOLDEN_T / "pred" / f"{entry}.lines.txt")
        anno = read_culane_lines(GOLDEN_T / "anno" / f"{entry}.lines.txt")
        seqs.setdefault(seq, []).append(Frame(pred, anno, size=size))
    return seqs


@pytest.mark.parametrize("threshold", ["0.5", "0.8"])
def test_golden_parity_with_mma_net(threshold: str) -> None:
    want = MMA[threshold]
    res = video.evaluate(_golden_first_frame_sizes(), (float(threshold),))
    assert res.totals[float(threshold)].f1 == want["F"]  # "all scenes F", every bit
    for s in res.per_sequence:  # what the C++ tool wrote for each video
        w = want["per_video"][s.name]
        assert (list(s.counts[float(threshold)]), f"{s.miou:.6g}") == ([w["tp"], w["fp"], w["fn"]], w["miou"])
    # "all scenes miou": the printed values summed in the order os.listdir gave the script, every bit ...
    by_name = {s.name: s.miou for s in res.per_sequence}
    assert video.dataset_miou([by_name[v] for v in want["video_order"]]) == want["miou"]
    # ... and in list order (which this package uses) the same up to the order of a float sum
    assert res.miou == pytest.approx(want["miou"], rel=1e-15, abs=0)


OUTCOMES = json.loads((GOLDEN_T / "expected.json").read_text())["outcomes"]


@pytest.mark.parametrize("name", sorted(OUTCOMES))
def test_mma_net_on_the_small_outcome_sets(name: str) -> None:
    import importlib.util

    spec = importlib.util.spec_from_file_location("make_cases", GOLDEN_T / "make_cases.py")
    cases = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(cases)
    seqs = {
        seq: [
            Frame([np.asarray(p, float) for p in pred], [np.asarray(a, float) for a in anno], size=size)
            for anno, pred, size in frames
        ]
        for seq, _, frames in cases.outcome_cases()[name][1]
    }
    for t, want in OUTCOMES[name]["mma_net"].items():
        res = video.evaluate(seqs, (float(t),))
        if "error" in want:  # no true positive anywhere: MMA-Net's script divides by zero; F is 0 here
            assert want["error"].startswith("ZeroDivisionError") and res.totals[float(t)].f1 == 0.0
            continue
        assert res.totals[float(t)].f1 == want["F"]
        by_name = {s.name: s.miou for s in res.per_sequence}
        assert video.dataset_miou([by_name[v] for v in want["video_order"]]) == want["miou"]


# ------------------------------------------------------------------- TuSimple json-lines as video sequences
def _tusimple_record(raw_file: str, lanes: list[np.ndarray]) -> dict | None:
    """One frame's CULane lanes as a TuSimple record, where that is exact: every x >= 0, each lane's rows strictly
    monotone and all in one direction (the points come back in their order); None where it is not."""
    ys = sorted({float(y) for lane in lanes for y in lane[:, 1]})
    steps = [np.sign(np.diff(lane[:, 1])) for lane in lanes if len(lane) > 1]
    if any((lane[:, 0] < 0).any() or len(set(lane[:, 1].tolist())) != len(lane) for lane in lanes):
        return None
    directions = {float(d) for s in steps for d in s}
    if len(directions) > 1:
        return None
    if directions == {-1.0}:
        ys = ys[::-1]
    ys = ys or [0.0]  # a frame without points still needs a row (lanes of no point: all -2)
    xs = [[dict(zip(lane[:, 1].tolist(), lane[:, 0].tolist(), strict=True)).get(y, -2) for y in ys] for lane in lanes]
    return {"raw_file": raw_file, "lanes": xs, "h_samples": ys}


def _golden_as_tusimple(tmp_path: Path) -> tuple[Path, Path, Path, Path, list[str]]:
    """The golden temporal set's sequences that TuSimple can hold exactly, in both formats: CULane text trees
    (copied), TuSimple json-lines (``<sequence>/<frame>.jpg``; a missing prediction file: no record), a --list
    and --sizes. Returns (text pred, text anno, json pred, json gt, sequences)."""
    from stamlane_eval.io import read_culane_lines

    entries = (GOLDEN_T / "list.txt").read_text().split()
    by_seq: dict[str, list[str]] = {}
    for entry in entries:
        by_seq.setdefault(entry.rsplit("/", 1)[0], []).append(entry)
    kept, gt_recs, pred_recs = [], [], []
    for seq, frames in by_seq.items():
        g = [_tusimple_record(f"{e}.jpg", read_culane_lines(GOLDEN_T / "anno" / f"{e}.lines.txt")) for e in frames]
        have = [e for e in frames if (GOLDEN_T / "pred" / f"{e}.lines.txt").exists()]
        p = [_tusimple_record(f"{e}.jpg", read_culane_lines(GOLDEN_T / "pred" / f"{e}.lines.txt")) for e in have]
        if all(r is not None for r in g + p):
            kept.append(seq)
            gt_recs += g
            pred_recs += p
    for name in ("anno", "pred"):
        for seq in kept:
            for src in (GOLDEN_T / name / seq).glob("*.lines.txt"):
                (tmp_path / name / seq).mkdir(parents=True, exist_ok=True)
                (tmp_path / name / seq / src.name).write_bytes(src.read_bytes())
    (tmp_path / "list.txt").write_text("".join(e + "\n" for e in entries if e.rsplit("/", 1)[0] in kept))
    sizes = json.loads((GOLDEN_T / "sizes.json").read_text())
    (tmp_path / "sizes.json").write_text(json.dumps({k: f"{w}x{h}" for k, (h, w) in sizes.items()}))
    for name, recs in (("gt.json", gt_recs), ("pred.json", pred_recs)):
        (tmp_path / name).write_text("".join(json.dumps(r) + "\n" for r in recs))
    return tmp_path / "pred", tmp_path / "anno", tmp_path / "pred.json", tmp_path / "gt.json", kept


@pytest.mark.parametrize("mode", [[], ["--temporal"], ["--list"]])
def test_tusimple_json_lines_score_as_culane_text(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, mode: list[str]
) -> None:
    """The same lanes as CULane text folders and as TuSimple json-lines (sequence: the folder of raw_file), in
    any mix: the same numbers, per sequence too, for the video metrics and RVLD's."""
    text_pred, text_anno, json_pred, json_gt, kept = _golden_as_tusimple(tmp_path)
    assert len(kept) >= 15  # most of the golden sequences, edge cases among them
    extra = ["--sizes", str(tmp_path / "sizes.json")]
    extra += ["--list", str(tmp_path / "list.txt")] if mode == ["--list"] else mode
    got = {}
    for pred, gt in ((text_pred, text_anno), (json_pred, json_gt), (text_pred, json_gt), (json_pred, text_anno)):
        per = tmp_path / f"seq-{pred.name}-{gt.name}.jsonl"
        code = main(["video", str(pred), str(gt), "--json", "--per-sequence", str(per), *extra])
        out, err = capsys.readouterr()
        assert code == 0 and err == "", err
        got[pred.name, gt.name] = (json.loads(out), per.read_text())
    want = got["pred", "anno"]
    assert want[0]["sequences"] == len(kept)
    for key, value in got.items():
        assert value == want, key


def test_tusimple_frames_of_the_generator(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """The generator's frame_labels/<clip>.json (one JSON list per clip, every frame) as ground truth and
    stamlane predict's predictions.json (json-lines, key frames only): frames in record order (1 .. 12, not
    1, 10, 11, 12, 2 ...), a frame without a record has no lanes, a prediction of an unlabelled frame is left out."""
    h = list(range(160, 360, 10))
    lane = [100 + 2 * i for i in range(len(h))]
    labels = tmp_path / "frame_labels"
    labels.mkdir()
    preds = []
    for clip in ("test-0000", "test-0001"):
        recs = [
            {"raw_file": f"clips/{clip}/{n}.jpg", "lanes": [lane], "h_samples": h, "occluded": []} for n in range(1, 13)
        ]
        (labels / f"{clip}.json").write_text(json.dumps(recs))
        preds += [{**r, "run_time": 5.0} for r in recs if r["raw_file"].endswith(("/12.jpg", "/8.jpg"))]
    preds.append({"raw_file": "clips/other/1.jpg", "lanes": [lane], "h_samples": h, "run_time": 5.0})
    (tmp_path / "predictions.json").write_text("".join(json.dumps(r) + "\n" for r in preds))
    code = main(["video", str(tmp_path / "predictions.json"), str(labels), "--size", "640x360", "--json"])
    out, err = capsys.readouterr()
    assert code == 0 and err == "", err
    res = json.loads(out)
    assert res["sequences"] == 2 and res["frames"] == 24 and res["0.5"]["tp"] == 4 and res["0.5"]["fn"] == 20
    frames = {
        (s, k): video.Frame(
            [np.array([[x, y] for x, y in zip(lane, h, strict=True)])] if k in (8, 12) else [],
            [np.array([[x, y] for x, y in zip(lane, h, strict=True)], dtype=float)],
            size=SIZE,
        )
        for s in ("clips/test-0000", "clips/test-0001")
        for k in range(1, 13)
    }
    want = video.evaluate({s: [frames[s, k] for k in range(1, 13)] for s in ("clips/test-0000", "clips/test-0001")})
    assert res == want.as_dict()  # record order is time order: the flicker count needs 8 and 12 where they are


def test_swapped_tusimple_records_are_refused(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """Labels given as PRED and predictions (with run_time) as GT: one line naming the order; --as-given scores
    them as given (P and R exchanged)."""
    h = list(range(160, 360, 10))
    gt = [{"raw_file": f"clips/c/{n}.jpg", "lanes": [[100 + n] * len(h)], "h_samples": h} for n in range(3)]
    pred = [{**r, "lanes": [[100] * len(h), [500] * len(h)], "run_time": 5.0} for r in gt]
    (tmp_path / "gt.json").write_text("".join(json.dumps(r) + "\n" for r in gt))
    (tmp_path / "pred.json").write_text("".join(json.dumps(r) + "\n" for r in pred))
    args = ["--size", "640x360", "--json"]
    assert main(["video", str(tmp_path / "pred.json"), str(tmp_path / "gt.json"), *args]) == 0
    right = json.loads(capsys.readouterr().out)["0.5"]
    assert main(["video", str(tmp_path / "gt.json"), str(tmp_path / "pred.json"), *args]) == 2
    out, err = capsys.readouterr()
    assert out == "" and len(err.strip().splitlines()) == 1 and "look swapped" in err and "PRED GT" in err
    assert main(["video", str(tmp_path / "gt.json"), str(tmp_path / "pred.json"), *args, "--as-given"]) == 0
    given = json.loads(capsys.readouterr().out)["0.5"]
    assert (given["fp"], given["fn"], given["precision"]) == (right["fn"], right["fp"], right["recall"])
