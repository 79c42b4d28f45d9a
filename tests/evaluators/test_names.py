"""Metric names, built and read in one place (`stamlane_eval.names`): every name the callback logs reads back to
itself, every key a metric computes belongs to the vocabulary, and names written another way are refused."""

from __future__ import annotations

import numpy as np
import pytest
from stamlane_eval import culane, temporal, video
from stamlane_eval.names import (
    METRICS,
    THRESHOLDED,
    UNTHRESHOLDED,
    MetricName,
    metric_key,
    metric_name,
    parse_metric_key,
    parse_metric_name,
)


def test_names_are_written_as_the_callback_always_wrote_them() -> None:
    assert metric_name("tusimple", "f1") == "tusimple_f1"
    assert metric_name("tusimple", "late", stage="val") == "val/tusimple_late"
    assert metric_name("culane", "f1", 0.5, stage="test") == "test/culane_f1@0.5"
    assert metric_name("culane", "precision", 0.3) == "culane_precision@0.3"
    assert metric_name("video", "miou", stage="val") == "val/video_miou"
    assert metric_name("video", "recall", 0.8) == "video_recall@0.8"
    assert metric_name("temporal", "rs", 0.5, stage="val") == "val/temporal_rs@0.5"
    assert metric_name("temporal", "rm", 0.8) == "temporal_rm@0.8"
    assert metric_key("f1", 0.5) == "f1@0.5" and metric_key("fp") == "fp" and metric_key("f1", 1e-5) == "f1@1e-05"


def test_every_name_of_the_vocabulary_reads_back_to_itself() -> None:
    for metric in METRICS:
        for quantity in UNTHRESHOLDED[metric]:
            for stage in (None, "val", "test"):
                name = metric_name(metric, quantity, stage=stage)
                assert parse_metric_name(name) == MetricName(metric, quantity, None, stage)
        for quantity in THRESHOLDED[metric]:
            for t in (0.3, 0.5, 0.8, 0.35, 0.0):
                name = metric_name(metric, quantity, t, stage="val")
                parsed = parse_metric_name(name)
                assert parsed == MetricName(metric, quantity, t, "val") and str(parsed) == name
                assert parse_metric_key(parsed.key) == (quantity, t)


@pytest.mark.parametrize(
    ("name", "problem"),
    [
        ("tusimple", "not a metric name"),
        ("iou_f1@0.5", "unknown metric 'iou'"),
        ("culane_miou", "culane gives no 'miou'"),
        ("culane_f1", "per IoU threshold"),
        ("tusimple_f1@0.5", "has no IoU threshold"),
        ("culane_f1@0.50", "not written as the metrics write it: 'culane_f1@0.5'"),
        ("culane_f1@half", "must be a number"),
        ("/tusimple_f1", "a stage is a non-empty word"),
        ("a/b/tusimple_f1", "a stage is a non-empty word"),
        ("val/recall_visible", "unknown metric 'recall'"),  # stamlane's own numbers are not the evaluators'
    ],
)
def test_names_the_metrics_do_not_write_are_refused(name: str, problem: str) -> None:
    with pytest.raises(ValueError, match=problem.replace("(", r"\(")):
        parse_metric_name(name)


def test_the_builder_refuses_what_no_metric_gives() -> None:
    with pytest.raises(ValueError, match="unknown metric"):
        metric_name("apollo", "f1", 0.5)
    with pytest.raises(ValueError, match="per IoU threshold"):
        metric_name("temporal", "rs")
    with pytest.raises(ValueError, match="no IoU threshold"):
        metric_name("video", "miou", 0.5)


# ---------------------------------------------------------------------------------------- the callback's names
class _Module:
    """Records what ``pl_module.log`` is given."""

    def __init__(self) -> None:
        self.device = pytest.importorskip("torch").device("cpu")
        self.logged: dict[str, float] = {}

    def log(self, name: str, value: float) -> None:
        self.logged[name] = value


def _clip() -> dict[str, list]:
    """Three frames of one clip, TuSimple rows and sizes: every metric of the callback has a number."""
    rows = list(range(160, 720, 10))
    ys = np.array(rows, dtype=float)
    gt = [np.stack([300 + 0.5 * ys, ys], 1), np.stack([1000 - 0.4 * ys, ys], 1)]
    frames = [[lane + np.array([dx, 0.0]) for lane in gt] for dx in (2.0, 25.0, 4.0)]
    return {
        "pred_lanes": frames,
        "gt_lanes": [gt] * 3,
        "h_samples": [rows] * 3,
        "orig_size": [(720, 1280)] * 3,
        "run_time": [10.0] * 3,
        "sequence": ["clip"] * 3,
    }


def test_every_name_the_callback_logs_reads_back_to_itself() -> None:
    pytest.importorskip("lightning.pytorch")
    from stamlane_eval.integrations.lightning import LaneEvalCallback

    cb = LaneEvalCallback(video=True, temporal=True)
    for stage in ("val", "test"):
        module = _Module()
        cb._reset(module)
        cb._keep(_clip())
        cb._log(module, stage)
        expected = {metric_name("tusimple", q, stage=stage) for q in ("accuracy", "fp", "fn", "f1", "late")}
        expected |= {metric_name("video", "miou", stage=stage)}
        for t in culane.IOU_THRESHOLDS:
            expected |= {metric_name("culane", q, t, stage=stage) for q in ("f1", "precision", "recall")}
        for t in video.VIDEO_IOU_THRESHOLDS:
            expected |= {metric_name("video", q, t, stage=stage) for q in ("f1", "precision", "recall")}
        for t in temporal.TEMPORAL_IOU_THRESHOLDS:
            expected |= {metric_name("temporal", q, t, stage=stage) for q in ("rs", "rj", "rm")}
        assert set(module.logged) == expected and len(expected) == 24
        for name in module.logged:
            parsed = parse_metric_name(name)
            assert str(parsed) == name and parsed.stage == stage
            assert metric_name(parsed.metric, parsed.quantity, parsed.threshold, stage=parsed.stage) == name


def test_every_key_a_metric_computes_is_in_the_vocabulary() -> None:
    pytest.importorskip("torchmetrics")
    from stamlane_eval.integrations.torchmetrics import (
        CULaneMetric,
        TemporalStabilityMetric,
        TuSimpleMetric,
        VideoMetric,
    )
    from stamlane_eval.tusimple import lanes_to_xs

    clip = _clip()
    metrics = {
        "tusimple": TuSimpleMetric(),
        "culane": CULaneMetric(),
        "video": VideoMetric(),
        "temporal": TemporalStabilityMetric(),
    }
    rows = clip["h_samples"][0]
    preds = [lanes_to_xs(lanes, rows) for lanes in clip["pred_lanes"]]
    gts = [lanes_to_xs(lanes, rows) for lanes in clip["gt_lanes"]]
    metrics["tusimple"].update(preds, gts, clip["h_samples"], clip["run_time"])
    metrics["culane"].update(clip["pred_lanes"], clip["gt_lanes"], clip["orig_size"])
    metrics["video"].update(clip["pred_lanes"], clip["gt_lanes"], clip["sequence"], clip["orig_size"])
    metrics["temporal"].update(clip["pred_lanes"], clip["gt_lanes"], clip["sequence"], clip["orig_size"])
    for metric, m in metrics.items():
        keys = set(m.compute())
        vocabulary = set(UNTHRESHOLDED[metric]) | {
            metric_key(q, t) for q in THRESHOLDED[metric] for t in getattr(m, "iou_thresholds", ())
        }
        assert keys == vocabulary, metric


def test_the_callback_takes_the_protocol_constants() -> None:
    pytest.importorskip("lightning.pytorch")
    from stamlane_eval.integrations.lightning import LaneEvalCallback

    cb = LaneEvalCallback()
    assert cb.culane_metric.iou_thresholds == culane.IOU_THRESHOLDS == (0.3, 0.5)
    assert cb.culane_metric.width == culane.LANE_WIDTH == 30
