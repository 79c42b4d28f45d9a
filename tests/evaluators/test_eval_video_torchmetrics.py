"""VideoMetric and TemporalStabilityMetric equal the functions; 2 DDP processes (gloo) give the numbers of one;
LaneEvalCallback logs them from a Trainer."""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("torchmetrics")
pl = pytest.importorskip("lightning.pytorch")

from stamlane_eval import temporal, video  # noqa: E402
from stamlane_eval.integrations.lightning import LaneEvalCallback  # noqa: E402
from stamlane_eval.integrations.torchmetrics import TemporalStabilityMetric, VideoMetric  # noqa: E402
from stamlane_eval.video import Frame  # noqa: E402

from .conftest import run_ddp_pair  # noqa: E402

WORKER = Path(__file__).parent / "ddp_video_worker.py"


def _worker() -> object:
    spec = importlib.util.spec_from_file_location("ddp_video_worker", WORKER)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


FRAMES = _worker().golden_frames()  # (sequence, preds, annos, (H, W)) in list order


def _sequences() -> dict[str, list[Frame]]:
    seqs: dict[str, list[Frame]] = {}
    for seq, pred, anno, size in FRAMES:
        seqs.setdefault(seq, []).append(Frame(pred, anno, size=size))
    return seqs


def _batches(metric: VideoMetric | TemporalStabilityMetric, tensors: bool = False) -> None:
    for s in range(0, len(FRAMES), 7):  # batches that cut sequences anywhere
        b = FRAMES[s : s + 7]
        preds = [[torch.as_tensor(x) for x in f[1]] if tensors else f[1] for f in b]
        metric.update(preds, [f[2] for f in b], [f[0] for f in b], [f[3] for f in b])


def test_temporal_metric_equals_function() -> None:
    want = temporal.evaluate(_sequences())
    m = TemporalStabilityMetric()
    _batches(m, tensors=True)
    got = m.compute()
    for t, c in want.totals.items():
        assert [int(got[f"{k}@{t:g}"]) for k in ("ns", "nj", "nm")] == [c.ns, c.nj, c.nm]
        assert [float(got[f"{k}@{t:g}"]) for k in ("rs", "rj", "rm")] == [c.rs, c.rj, c.rm]
    assert int(m.pairs) == want.pairs and int(m.images) == want.frames
    m.reset()  # forgets the last frame of every sequence too
    seq, pred, anno, size = FRAMES[0]
    assert m([pred], [anno], [seq], [size]) is None  # forward only updates: a batch has no stability of its own
    assert int(m.pairs) == 0 and int(m.images) == 1 and math.isnan(float(m.compute()["rs@0.5"]))


def test_video_metric_equals_function() -> None:
    want = video.evaluate(_sequences())
    m = VideoMetric()
    _batches(m)
    got = m.compute()
    assert float(got["miou"]) == want.miou
    for t, c in want.totals.items():
        assert float(got[f"f1@{t:g}"]) == c.f1 and int(got[f"tp@{t:g}"]) == c.tp


def test_bad_updates() -> None:
    m = TemporalStabilityMetric()
    with pytest.raises(ValueError, match="sequence names"):
        m.update([[]], [[]], ["a", "b"])
    with pytest.raises(ValueError, match=r"sequence 'a', frame 0 of this update: .*one place"):
        m.update([[np.ones((2, 2))]], [[np.ones((2, 2))]], ["a"], [(360, 640)])
    with pytest.raises(ValueError, match="protocol"):
        TemporalStabilityMetric(protocol="culane")


def test_ddp_two_processes_equal_one(tmp_path: Path) -> None:
    ddp = run_ddp_pair(WORKER, tmp_path / "ddp.json", timeout=180)
    tm, vm = TemporalStabilityMetric(), VideoMetric()
    _batches(tm)
    _batches(vm)
    single = {f"temporal_{k}": float(v) for k, v in tm.compute().items()}
    single.update({f"video_{k}": float(v) for k, v in vm.compute().items()})
    assert set(ddp) == set(single)
    for k, v in single.items():
        if k.startswith("temporal_") or "@" in k:  # counts, and ratios of counts: exactly
            assert ddp[k] == v, k
    # the mIoU: a sequence's frames gathered from two processes are summed in another order
    assert ddp["video_miou"] == pytest.approx(single["video_miou"], rel=1e-12)


# ------------------------------------------------------------------------------------------ the callback
class _Frames(torch.utils.data.Dataset):
    def __len__(self) -> int:
        return len(FRAMES)

    def __getitem__(self, i: int) -> int:
        return i


class _KnownFrames(pl.LightningModule):
    def __init__(self) -> None:
        super().__init__()
        self.layer = torch.nn.Linear(1, 1)

    def validation_step(self, batch: list[int], batch_idx: int) -> dict:
        fr = [FRAMES[int(i)] for i in batch]
        return {
            "pred_lanes": [f[1] for f in fr],
            "gt_lanes": [f[2] for f in fr],
            "h_samples": [None] * len(fr),
            "orig_size": [f[3] for f in fr],
            "sequence": [f[0] for f in fr],
        }


def test_callback_logs_video_and_temporal_metrics() -> None:
    cb = LaneEvalCallback(tusimple=False, culane=False, video=True, temporal=True)
    trainer = pl.Trainer(
        callbacks=[cb], logger=False, enable_checkpointing=False, enable_progress_bar=False, enable_model_summary=False
    )
    loader = torch.utils.data.DataLoader(_Frames(), batch_size=6, collate_fn=list)  # frames in time order
    logged = trainer.validate(_KnownFrames(), loader, verbose=False)[0]
    t_want = temporal.evaluate(_sequences()).totals
    v_want = video.evaluate(_sequences())
    assert logged["val/temporal_rs@0.5"] == pytest.approx(t_want[0.5].rs)
    assert logged["val/temporal_rm@0.8"] == pytest.approx(t_want[0.8].rm)
    assert logged["val/video_miou"] == pytest.approx(v_want.miou)
    assert logged["val/video_f1@0.8"] == pytest.approx(v_want.totals[0.8].f1)
    assert not any(k.startswith("val/culane") for k in logged)


def test_callback_needs_sequences() -> None:
    cb = LaneEvalCallback(tusimple=False, culane=False, temporal=True)
    out = {"pred_lanes": [[]], "gt_lanes": [[]], "h_samples": [None], "orig_size": [(360, 640)]}
    with pytest.raises(ValueError, match="'sequence'"):
        cb._keep(out)
