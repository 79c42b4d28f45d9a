"""LaneEvalCallback inside a real lightning.Trainer: logs the numbers of the functions, val and test stages."""

from __future__ import annotations

import warnings
from types import ModuleType

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pl = pytest.importorskip("lightning.pytorch")

from stamlane_eval import culane, tusimple  # noqa: E402
from stamlane_eval.integrations.lightning import LaneEvalCallback  # noqa: E402


class _Images(torch.utils.data.Dataset):
    def __init__(self, n: int) -> None:
        self.n = n

    def __len__(self) -> int:
        return self.n

    def __getitem__(self, i: int) -> int:
        return i


class _KnownLanes(pl.LightningModule):
    """validation_step returns fixed lanes: TuSimple images first, then CULane images (no h_samples)."""

    def __init__(self, images: list[dict]) -> None:
        super().__init__()
        self.images = images
        self.layer = torch.nn.Linear(1, 1)

    def _step(self, batch: list[int]) -> dict:
        ims = [self.images[i] for i in batch]
        return {k: [im[k] for im in ims] for k in ("pred_lanes", "gt_lanes", "h_samples", "orig_size", "run_time")}

    def validation_step(self, batch: list[int], batch_idx: int) -> dict:
        return self._step(batch)

    def test_step(self, batch: list[int], batch_idx: int) -> dict:
        return self._step(batch)

    def training_step(self, batch: list[int], batch_idx: int) -> torch.Tensor:
        return self.layer(torch.ones(1, 1)).sum()

    def configure_optimizers(self) -> torch.optim.Optimizer:
        return torch.optim.SGD(self.parameters(), lr=0.0)


def _images(golden: ModuleType) -> list[dict]:
    preds, gts = golden.tusimple_records()
    out = []
    for p, g in zip(preds, gts, strict=True):
        out.append(
            {
                "pred_lanes": golden.xs_to_points(p["lanes"], g["h_samples"]),
                "gt_lanes": [torch.as_tensor(x) for x in golden.xs_to_points(g["lanes"], g["h_samples"])],
                "h_samples": g["h_samples"],
                "orig_size": (720, 1280),
                "run_time": p["run_time"],
            }
        )
    cp, cg = golden.culane_lanes()
    for p, g in zip(cp, cg, strict=True):
        out.append({"pred_lanes": p, "gt_lanes": g, "h_samples": None, "orig_size": (590, 1640), "run_time": 1.0})
    return out


def _expected(images: list[dict], prefix: str, time_limit: bool = True) -> dict[str, float]:
    ts = [im for im in images if im["h_samples"] is not None]
    res = tusimple.evaluate_batch(
        [tusimple.lanes_to_xs(im["pred_lanes"], im["h_samples"]) for im in ts],
        [tusimple.lanes_to_xs([np.asarray(x) for x in im["gt_lanes"]], im["h_samples"]) for im in ts],
        [im["h_samples"] for im in ts],
        [im["run_time"] for im in ts] if time_limit else None,
    )
    acc = sum(r.acc for r in res) / len(res)
    fp = sum(r.fp for r in res) / len(res)
    fn = sum(r.fn for r in res) / len(res)
    per = [
        culane.evaluate_image(
            [np.asarray(x) for x in im["pred_lanes"]], [np.asarray(x) for x in im["gt_lanes"]], size=im["orig_size"]
        )
        for im in images
    ]
    cu = culane.aggregate(per)
    out = {
        f"{prefix}/tusimple_accuracy": acc,
        f"{prefix}/tusimple_fp": fp,
        f"{prefix}/tusimple_fn": fn,
        f"{prefix}/tusimple_f1": tusimple.paper_f1(fp, fn),
        f"{prefix}/tusimple_late": float(sum(im["run_time"] > tusimple.MAX_RUN_TIME_MS for im in ts)),
    }
    for t in (0.3, 0.5):
        c = cu.totals[t]
        out |= {
            f"{prefix}/culane_f1@{t}": c.f1,
            f"{prefix}/culane_precision@{t}": c.precision,
            f"{prefix}/culane_recall@{t}": c.recall,
        }
    return out


def test_callback_in_trainer(golden: ModuleType) -> None:
    torch.set_num_threads(1)
    images = _images(golden)
    model = _KnownLanes(images)
    loader = torch.utils.data.DataLoader(_Images(len(images)), batch_size=4, collate_fn=list)
    cb = LaneEvalCallback()
    trainer = pl.Trainer(
        accelerator="cpu",
        max_epochs=1,
        limit_train_batches=1,
        num_sanity_val_steps=1,
        callbacks=[cb],
        logger=False,
        enable_checkpointing=False,
        enable_progress_bar=False,
        enable_model_summary=False,
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        trainer.fit(model, loader, loader)
    assert not [w for w in caught if "run_time over 200 ms" in str(w.message)]  # validation: no 200 ms rule
    want = _expected(images, "val", time_limit=False)
    got = {k: float(v) for k, v in trainer.callback_metrics.items() if k.startswith("val/")}
    assert got["val/tusimple_late"] == 1.0  # counted, not applied
    assert set(got) == set(want)
    for k, v in want.items():
        assert got[k] == pytest.approx(v, rel=1e-6), k  # logged as float32
    with pytest.warns(UserWarning, match="run_time over 200 ms") as caught:
        test = trainer.test(model, loader, verbose=False)[0]
    late = [w for w in caught if "run_time over 200 ms" in str(w.message)]
    assert len(late) == 1 and "1 of 22 images" in str(late[0].message)  # the golden image at 200.001 ms
    assert "LaneEvalCallback(tusimple_time_limit=False)" in str(late[0].message)
    want = _expected(images, "test")
    assert set(test) == set(want)
    for k, v in want.items():
        assert test[k] == pytest.approx(v, rel=1e-6), k


def test_callback_warns_about_late_images_once(golden: ModuleType) -> None:
    """The 200 ms rule said once per callback (not every validation), its count logged every time; without the
    rule (``tusimple_time_limit=False``) the late image is scored on its lanes and nothing is said."""
    images = [im for im in _images(golden) if im["h_samples"] is not None]
    outputs = {k: [im[k] for im in images] for k in ("pred_lanes", "gt_lanes", "h_samples", "orig_size", "run_time")}

    class _Module:
        device = torch.device("cpu")

        def __init__(self) -> None:
            self.logged: dict[str, float] = {}

        def log(self, name: str, value: float) -> None:
            self.logged[name] = value

    cases = [(True, "val", 1), (False, "val", 0), ("test", "val", 0), ("test", "test", 1), (False, "test", 0)]
    for time_limit, stage, said in cases:
        cb, module = LaneEvalCallback(culane=False, tusimple_time_limit=time_limit), _Module()
        applied = time_limit is True or (time_limit == "test" and stage == "test")
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            for _ in range(2):  # two validations
                cb._reset(module)
                cb._keep(outputs)
                cb._log(module, stage)
        assert sum("run_time over 200 ms" in str(w.message) for w in caught) == said, (time_limit, stage)
        assert module.logged[f"{stage}/tusimple_late"] == 1.0  # counted whether the rule applies or not
        want = _expected(images, stage)[f"{stage}/tusimple_accuracy"]  # with the rule
        assert (module.logged[f"{stage}/tusimple_accuracy"] == want) == applied  # the late image: missed, or not
    with pytest.raises(ValueError, match="tusimple_time_limit"):
        LaneEvalCallback(tusimple_time_limit="val")  # type: ignore[arg-type]


def test_callback_fixed_size_and_bad_outputs(golden: ModuleType) -> None:
    cb = LaneEvalCallback(tusimple=False, culane_size=(590, 1640))
    images = _images(golden)[-3:]
    cb._keep({k: [im[k] for im in images] for k in ("pred_lanes", "gt_lanes", "h_samples", "orig_size")})
    cb._score([record for _, record in cb._records])
    assert int(cb.culane_metric.images) == 3 and int(cb.tusimple_metric.images) == 0
    with pytest.raises(ValueError, match="pred_lanes"):
        cb._keep({"loss": 1.0})
    with pytest.raises(ValueError, match="culane_size"):
        LaneEvalCallback(culane_size=(0, 5))
