"""Every aggregation of `stamlane_eval.aggregate`, each formula once, on the golden data: fed the official tools'
per-image (per-pair, per-video) numbers, each function gives the official totals; the functions, the
torchmetrics classes and the bootstrap statistics that fold with them give the same numbers."""

from __future__ import annotations

import json
import math
from pathlib import Path
from types import SimpleNamespace

import pytest
from stamlane_eval import aggregate, culane, stats, temporal, video
from stamlane_eval.aggregate import (
    TuSimpleSums,
    count_update,
    dataset_miou,
    paper_f1,
    prf,
    sequence_miou,
    stability_rates,
    tusimple_compute,
    tusimple_update,
)
from stamlane_eval.io import read_culane_lines
from stamlane_eval.video import Frame

GOLDEN = Path(__file__).parent / "golden"
TEMPORAL = json.loads((GOLDEN / "temporal" / "expected.json").read_text())
CULANE = json.loads((GOLDEN / "culane" / "expected.json").read_text())


def _golden_sequences(sizes_of_first_frame: bool = False) -> dict[str, list[Frame]]:
    """The golden temporal set; every frame at its own size (RVLD) or at its video's first (MMA-Net)."""
    sizes = json.loads((GOLDEN / "temporal" / "sizes.json").read_text())
    seqs: dict[str, list[Frame]] = {}
    for entry in (GOLDEN / "temporal" / "list.txt").read_text().split():
        seq = entry.rsplit("/", 1)[0]
        size = seqs[seq][0].size if sizes_of_first_frame and seq in seqs else tuple(sizes[entry])
        pred = read_culane_lines(GOLDEN / "temporal" / "pred" / f"{entry}.lines.txt")
        anno = read_culane_lines(GOLDEN / "temporal" / "anno" / f"{entry}.lines.txt")
        seqs.setdefault(seq, []).append(Frame(pred, anno, size=size))
    return seqs


# ------------------------------------------------------------------------------------------------ TuSimple
def test_tusimple_sums_of_the_official_per_image_numbers_give_the_official_totals() -> None:
    want = json.loads((GOLDEN / "tusimple_expected.json").read_text())
    per_image = [SimpleNamespace(**r, matched=0, n_pred=0, n_gt=0) for r in want["per_image"]]
    whole = tusimple_compute(tusimple_update(TuSimpleSums(), per_image))
    assert {k: whole[k] for k in ("accuracy", "fp", "fn")} == want["totals"]  # lane.py's sums, every bit
    assert whole["f1"] == paper_f1(want["totals"]["fp"], want["totals"]["fn"])
    sums = TuSimpleSums()
    for start in range(0, len(per_image), 5):  # in batches, as the torchmetrics class adds them: the same bits
        sums = tusimple_update(sums, per_image[start : start + 5])
    assert tusimple_compute(sums) == whole
    assert tusimple_compute(TuSimpleSums())["accuracy"] == 0.0  # no image
    assert paper_f1(0.0339, 0.0299) == pytest.approx(0.9681, abs=5e-5)  # the paper's 96.81


# ------------------------------------------------------------------------------------------- CULane, video F
@pytest.mark.parametrize("variant", ["cpp", "lanedet"])
def test_count_sums_and_prf_of_the_official_per_image_counts(variant: str) -> None:
    thresholds = (0.3, 0.5)
    per_image = [{t: tuple(r[variant][str(t)]) for t in thresholds} for r in CULANE["per_image"]]
    sums = count_update([(0, 0, 0)] * 2, per_image, thresholds)
    assert sums == [tuple(int(sum(c[t][k] for c in per_image)) for k in range(3)) for t in thresholds]
    assert count_update(count_update([(0, 0, 0)] * 2, per_image[:7], thresholds), per_image[7:], thresholds) == sums
    for tp, fp, fn in sums:
        precision, recall = tp / (tp + fp), tp / (tp + fn)  # lanedet's eval_predictions, as written there
        assert prf(tp, fp, fn) == (precision, recall, 2 * precision * recall / (precision + recall))
    assert prf(0, 0, 0) == (0.0, 0.0, 0.0) and prf(0, 3, 2) == (0.0, 0.0, 0.0)  # 0 where undefined


def test_the_culane_function_and_class_fold_with_count_update(golden) -> None:
    preds, gts = golden.culane_lanes()
    res = culane.evaluate(preds, gts)
    sums = count_update([(0, 0, 0)] * 2, (r.counts for r in res.per_image), culane.IOU_THRESHOLDS)
    assert [res.totals[t] for t in culane.IOU_THRESHOLDS] == [culane.counts_to_prf(*c) for c in sums]
    cpp = [r["cpp"] for r in CULANE["per_image"]]
    assert [list(r.counts[0.5]) for r in res.per_image] == [c["0.5"] for c in cpp]  # the C++ tool's, per image


def test_video_counts_and_miou_give_mma_net_numbers() -> None:
    seqs = _golden_sequences(sizes_of_first_frame=True)
    for threshold in ("0.5", "0.8"):
        want = TEMPORAL["mma_net"][threshold]
        t = float(threshold)
        res = video.evaluate(seqs, (t,))
        per_video = [{t: (w["tp"], w["fp"], w["fn"])} for w in want["per_video"].values()]
        (sums,) = count_update([(0, 0, 0)], per_video, (t,))
        assert prf(*sums)[2] == res.totals[t].f1 == want["F"]  # "all scenes F", every bit
        for s in res.per_sequence:  # a sequence's mIoU as evaluate.cpp prints it
            assert f"{sequence_miou(s.frame_miou):.6g}" == want["per_video"][s.name]["miou"]
        printed = [float(want["per_video"][v]["miou"]) for v in want["video_order"]]
        assert dataset_miou(printed) == want["miou"]  # "all scenes miou", in the script's order, every bit
    assert sequence_miou([]) is None and dataset_miou([]) == 0.0
    assert video.dataset_miou is dataset_miou and video.MMA_NET_DIGITS == aggregate.MMA_NET_DIGITS == 6


# ---------------------------------------------------------------------------------------------- temporal
@pytest.mark.parametrize("threshold", ["0.5", "0.8", "0.0", "0.3"])
def test_pair_counts_and_shares_give_rvld_totals(threshold: str) -> None:
    want = TEMPORAL["rvld"]["vil100"][threshold]
    t = float(threshold)
    (sums,) = count_update([(0, 0, 0)], ({t: tuple(p)} for p in want["per_pair"]), (t,))
    totals = want["totals"]
    assert sums == (totals["Ns"], totals["Nj"], totals["Nm"])
    rates = stability_rates(*sums)
    assert rates == tuple(math.nan if totals[k] is None else totals[k] for k in ("Rs", "Rj", "Rm"))  # every bit
    assert temporal.StabilityCounts(*sums).as_dict() == totals


def test_the_temporal_function_sums_every_pair_of_every_sequence() -> None:
    res = temporal.evaluate(_golden_sequences(), (0.5, 0.8))
    for t in (0.5, 0.8):
        pairs = [p for s in res.per_sequence for p in s.per_pair]
        (sums,) = count_update([(0, 0, 0)], pairs, (t,))
        assert res.totals[t] == temporal.StabilityCounts(*sums)
        by_sequence = [{t: (s.counts[t].ns, s.counts[t].nj, s.counts[t].nm)} for s in res.per_sequence]
        assert count_update([(0, 0, 0)], by_sequence, (t,)) == [sums]
    assert all(math.isnan(r) for r in stability_rates(0, 0, 0))


# ------------------------------------------------------------------------------------ the bootstrap statistics
def test_statistics_of_mean_counts_are_the_evaluators_formulas(golden) -> None:
    preds, gts = golden.culane_lanes()
    res = culane.evaluate(preds, gts)
    for t in culane.IOU_THRESHOLDS:
        counts = stats.culane_counts(res.per_image, t)
        assert stats.f1_of_counts(counts.sum(0)) == res.totals[t].f1  # the sums: the evaluator's F1, every bit
        assert stats.f1_of_counts(counts.mean(0)) == prf(*counts.mean(0))[2]
        tp, fp, fn = counts.mean(0)  # the formula the statistic used before, 2TP / (2TP + FP + FN): within 2 ulp
        assert stats.f1_of_counts(counts.mean(0)) == pytest.approx(2 * tp / (2 * tp + fp + fn), rel=5e-16, abs=0)
    seq = temporal.evaluate(_golden_sequences(), (0.5, 0.8))
    for t in (0.5, 0.8):
        counts = stats.temporal_counts(seq.per_sequence, t)
        c = seq.totals[t]
        assert (stats.rs_of_counts(counts.sum(0)), stats.rj_of_counts(counts.sum(0))) == (c.rs, c.rj)  # every bit
        means = counts.mean(0)
        shares = [float(means[k]) / float(means[0] + means[1] + means[2]) for k in range(3)]  # as before
        assert [stats.rs_of_counts(means), stats.rj_of_counts(means), stats.rm_of_counts(means)] == shares
        assert stats.rm_of_counts(means) == pytest.approx(c.rm, rel=1e-15)


# ----------------------------------------------------------------------------------- the torchmetrics classes
def test_the_video_classes_fold_as_the_functions_on_the_golden_set() -> None:
    pytest.importorskip("torchmetrics")
    from stamlane_eval.integrations.torchmetrics import TemporalStabilityMetric, VideoMetric

    seqs = _golden_sequences()
    frames = [(name, f) for name, fs in seqs.items() for f in fs]  # in time order within each sequence
    v_metric, t_metric = VideoMetric(), TemporalStabilityMetric()
    for start in range(0, len(frames), 7):  # batches that cut sequences: the sums do not care
        batch = frames[start : start + 7]
        args = ([f.preds for _, f in batch], [f.target for _, f in batch], [n for n, _ in batch])
        v_metric.update(*args, [f.size for _, f in batch])
        t_metric.update(*args, [f.size for _, f in batch])
    v_want = video.evaluate(seqs)
    v_got = v_metric.compute()
    assert float(v_got["miou"]) == v_want.miou
    t_want = temporal.evaluate(seqs)
    t_got = t_metric.compute()
    for t in video.VIDEO_IOU_THRESHOLDS:
        c = v_want.totals[t]
        assert [int(v_got[f"{k}@{t:g}"]) for k in ("tp", "fp", "fn")] == [c.tp, c.fp, c.fn]
        assert float(v_got[f"f1@{t:g}"]) == c.f1
        s = t_want.totals[t]
        assert [int(t_got[f"{k}@{t:g}"]) for k in ("ns", "nj", "nm")] == [s.ns, s.nj, s.nm]
        assert [float(t_got[f"{k}@{t:g}"]) for k in ("rs", "rj", "rm")] == [s.rs, s.rj, s.rm]
    assert int(t_metric.pairs) == t_want.pairs == 85
