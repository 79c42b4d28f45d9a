"""stamlane.training.module: the LightningModule's steps, the poly schedule, the weights-only checkpoint."""

from __future__ import annotations

import functools

import numpy as np
import pytest
import torch
from torch.utils.data import DataLoader

from stamlane.models import STAM, LaneDecoder, VGGEncoder
from stamlane.predict.postprocess import PostprocessConfig
from stamlane.training.module import PolyLR, StamLaneModule
from tests.cpu_trainer import cpu_trainer

torch.set_num_threads(1)
H, W, T = 32, 64, 2


def _module(**kwargs: object) -> StamLaneModule:
    torch.manual_seed(0)
    return StamLaneModule(
        VGGEncoder(width=0.125),
        functools.partial(STAM, mode="mixed", order="cs", reduction=4),
        LaneDecoder,
        num_frames=T,
        image_size=(H, W),
        postprocess=PostprocessConfig(min_cluster_pixels=5, min_samples=3),
        **kwargs,
    )


def _batch(size: int = 2) -> dict:
    """A batch as ``stamlane.data.collate_clips`` builds it (see ``stamlane.types``): two vertical lanes."""
    binary = torch.zeros(size, H, W, dtype=torch.int64)
    instance = torch.zeros(size, H, W, dtype=torch.int64)
    for lane_id, x in enumerate((16, 44), start=1):
        binary[:, 8:, x : x + 2] = 1
        instance[:, 8:, x : x + 2] = lane_id
    frames = torch.rand(size, T, 3, H, W) * 0.2
    frames[:, :, :, binary[0].bool()] = 1.0
    scale = 10.0  # original image = 10x the network input
    meta = {
        "raw_file": "clips/0/20.jpg",
        "orig_size": (H * 10, W * 10),
        "net_from_orig": [[1 / scale, 0, 0], [0, 1 / scale, 0], [0, 0, 1]],
        "h_samples": list(range(80, 320, 10)),
        "frame_paths": [],
        "format": "tusimple",
    }
    lanes = [np.array([[x * scale + 5, y] for y in range(80, 320, 10)], dtype=np.float64) for x in (16, 44)]
    return {"frames": frames, "binary": binary, "instance": instance, "lanes": [lanes] * size, "meta": [meta] * size}


def test_training_step_logs_terms_and_backprops() -> None:
    module = _module()
    logged = {}
    module.log = lambda name, value, **kw: logged.__setitem__(name, float(value.detach()))  # type: ignore[method-assign]
    loss = module.training_step(_batch(), 0)
    loss.backward()
    assert set(logged) == {"train/loss", "train/loss_seg", "train/loss_var", "train/loss_dist", "train/loss_reg"}
    assert np.isfinite(list(logged.values())).all()
    grads = [p.grad for p in module.parameters() if p.requires_grad]
    assert all(g is not None for g in grads) and any(g.abs().sum() > 0 for g in grads)


def test_validation_step_returns_callback_dict() -> None:
    module = _module().eval()
    module.log = lambda *a, **k: None  # type: ignore[method-assign]
    with torch.no_grad():
        out = module.validation_step(_batch(), 0)
    assert set(out) >= {"pred_lanes", "gt_lanes", "h_samples", "orig_size", "run_time"}
    assert len(out["pred_lanes"]) == 2 and out["orig_size"] == [(H * 10, W * 10)] * 2
    assert all(ms > 0 for ms in out["run_time"])
    for lanes in out["pred_lanes"]:  # untrained: any number of lanes, but well formed in original pixels
        for lane in lanes:
            assert lane.ndim == 2 and lane.shape[1] == 2
            assert (lane[:, 0] >= 0).all() and (lane[:, 0] <= 639).all()


def test_bad_inputs() -> None:
    module = _module()
    with pytest.raises(ValueError, match=r"expected clips of 2 frames, got 3"):
        module(torch.zeros(1, 3, 3, H, W))
    with pytest.raises(ValueError, match="multiples of the encoder stride 16"):
        StamLaneModule(VGGEncoder(0.125), STAM, LaneDecoder, image_size=(30, 64))


def test_poly_lr() -> None:
    param = torch.nn.Parameter(torch.zeros(1))
    opt = torch.optim.SGD([param], lr=1.0, momentum=0.9)
    sched = PolyLR(opt, total_steps=10, power=0.9)
    lrs = []
    for _ in range(10):
        lrs.append(opt.param_groups[0]["lr"])
        opt.step()
        sched.step()
    assert lrs[0] == 1.0
    assert np.allclose(lrs, [(1 - s / 10) ** 0.9 for s in range(10)])
    assert opt.param_groups[0]["lr"] == 0.0


def test_fit_bf16_channels_last_and_weights_only_checkpoint(tmp_path) -> None:
    module = _module(bf16=True, channels_last=True)
    batches = DataLoader([_batch()] * 2, batch_size=None, collate_fn=lambda b: b)
    trainer = cpu_trainer(max_steps=2, limit_val_batches=0)
    trainer.fit(module, train_dataloaders=batches)
    conv = module.net.encoder.stages[1][1]
    assert conv.weight.is_contiguous(memory_format=torch.channels_last)
    assert trainer.lr_scheduler_configs[0].scheduler.last_epoch == 2
    path = tmp_path / "m.ckpt"
    trainer.save_checkpoint(path)
    ckpt = torch.load(path, weights_only=True)  # no pickled objects in our checkpoints
    assert "state_dict" in ckpt and "encoder" not in ckpt.get("hyper_parameters", {})
