"""torchmetrics classes equal the per-image functions; 2 DDP processes (gloo) give the numbers of one."""

from __future__ import annotations

import warnings
from pathlib import Path
from types import ModuleType

import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("torchmetrics")

from stamlane_eval import culane, tusimple  # noqa: E402
from stamlane_eval.integrations.torchmetrics import CULaneMetric, TuSimpleMetric  # noqa: E402

from .conftest import run_ddp_pair  # noqa: E402


def _tusimple_update(metric: TuSimpleMetric, preds: list[dict], gts: list[dict]) -> None:
    for s in range(0, len(preds), 5):  # several batches
        p, g = preds[s : s + 5], gts[s : s + 5]
        metric.update(
            [x["lanes"] for x in p], [x["lanes"] for x in g], [x["h_samples"] for x in g], [x["run_time"] for x in p]
        )


WORKER = Path(__file__).parent / "ddp_worker.py"


def test_tusimple_metric_equals_function(golden: ModuleType) -> None:
    preds, gts = golden.tusimple_records()
    want = tusimple.evaluate(preds, gts)
    m = TuSimpleMetric()
    _tusimple_update(m, preds, gts)
    got = m.compute()
    assert float(got["accuracy"]) == want.accuracy
    assert float(got["fp"]) == want.fp
    assert float(got["fn"]) == want.fn
    assert float(got["f1"]) == want.f1
    assert float(got["lane_f1"]) == want.lane_f1
    m.reset()
    assert int(m.images) == 0


def test_tusimple_metric_says_the_200_ms_rule(golden: ModuleType) -> None:
    """compute warns once with the count of images scored as missed for their run_time and returns it as late;
    time_limit=False scores them on their lanes (as tusimple.evaluate(..., time_limit=False)) and says nothing."""
    preds, gts = golden.tusimple_records()
    m = TuSimpleMetric()
    _tusimple_update(m, preds, gts)
    with pytest.warns(UserWarning, match=r"1 of 22 images have a run_time over 200 ms") as caught:
        got = m.compute()
    assert len(caught) == 1 and "TuSimpleMetric(time_limit=False)" in str(caught[0].message)
    assert int(got["late"]) == 1 == tusimple.evaluate(preds, gts).late_images
    free = TuSimpleMetric(time_limit=False)
    _tusimple_update(free, preds, gts)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = free.compute()
    want = tusimple.evaluate(preds, gts, time_limit=False)
    assert float(got["accuracy"]) == want.accuracy and float(got["fn"]) == want.fn and int(got["late"]) == 1
    assert want.accuracy != tusimple.evaluate(preds, gts).accuracy


@pytest.mark.parametrize("batch", [1, 3, 7, 1000])
def test_class_and_function_share_one_aggregation(golden: ModuleType, batch: int) -> None:
    """The golden images, then the same images again under other names (repeated content, early returns, a six-lane
    image, a negative per-image FP among them), in batches of any size: the class and the function give the same
    numbers to the last bit, dividing by the same count of images."""
    preds, gts = golden.tusimple_records()
    preds = preds + [{**p, "raw_file": "again/" + p["raw_file"]} for p in preds]
    gts = gts + [{**g, "raw_file": "again/" + g["raw_file"]} for g in gts]
    want = tusimple.evaluate(preds, gts)
    assert any(r.early_return for r in want.per_image) and any(r.fp < 0 or r.acc > 1 for r in want.per_image)
    by_name = {g["raw_file"]: g for g in gts}
    m = TuSimpleMetric()
    for s in range(0, len(preds), batch):
        p = preds[s : s + batch]
        g = [by_name[x["raw_file"]] for x in p]
        m.update(
            [x["lanes"] for x in p], [x["lanes"] for x in g], [x["h_samples"] for x in g], [x["run_time"] for x in p]
        )
    got = {k: float(v) for k, v in m.compute().items()}
    assert int(m.images) == want.images == 2 * len(golden.tusimple_records()[0])
    for name in ("accuracy", "fp", "fn", "f1", "lane_precision", "lane_recall", "lane_f1"):
        assert got[name] == getattr(want, name), name
    with pytest.raises(tusimple.TuSimpleInputError, match="two labels for one image"):  # the function refuses a
        tusimple.evaluate(preds + preds[:1], gts + gts[:1])  # repeated NAME; the class, given no names, cannot see one


@pytest.mark.parametrize("variant", ["official", "lanedet"])
def test_culane_metric_equals_function(variant: str, golden: ModuleType) -> None:
    preds, gts = golden.culane_lanes()
    want = culane.evaluate(preds, gts, variant=variant)
    m = CULaneMetric(variant=variant)
    m.update(preds[:7], [[torch.as_tensor(x) for x in g] for g in gts[:7]])
    m.update(preds[7:], gts[7:], sizes=[(590, 1640)] * (len(preds) - 7))
    got = m.compute()
    for t in (0.3, 0.5):
        c = want.totals[t]
        assert (int(got[f"tp@{t:g}"]), int(got[f"fp@{t:g}"]), int(got[f"fn@{t:g}"])) == (c.tp, c.fp, c.fn)
        assert float(got[f"f1@{t:g}"]) == c.f1


def test_ddp_two_processes_equal_one(tmp_path: Path, golden: ModuleType) -> None:
    ddp = run_ddp_pair(WORKER, tmp_path / "ddp.json", timeout=120)
    preds, gts = golden.tusimple_records()
    one = TuSimpleMetric()
    _tusimple_update(one, preds, gts)
    cp, cg = golden.culane_lanes()
    cu = CULaneMetric()
    cu.update(cp, cg)
    single = {k: float(v) for k, v in {**one.compute(), **cu.compute()}.items()}
    assert set(ddp) == set(single)
    for k, v in single.items():
        assert ddp[k] == pytest.approx(v, rel=1e-12, abs=1e-12), k  # float sums: order of addition differs
    assert ddp["tp@0.5"] == single["tp@0.5"] and ddp["lane_precision"] == single["lane_precision"]
