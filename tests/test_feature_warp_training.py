"""Training with feature-space alignment: ``warp="feature"`` data, `StamLaneModule` on such batches and the
streaming predictor on the same path (the stream benchmark's fine-tuning: tests/benchmarks/test_stream.py)."""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch

import stamlane.training.module
from stamlane.cli import main as cli_main
from stamlane.data import NET_HOMOGRAPHIES, TuSimpleClips, collate_clips, net_homographies
from stamlane.data.datamodule import ClipDataModule
from stamlane.data.options import ClipOptions, LoaderOptions
from stamlane.data.transforms import ClipTransform
from stamlane.models import STAM, LaneDecoder, SimpleAdd, VGGEncoder, forward_feature_aligned
from stamlane.predict.postprocess import PostprocessConfig
from stamlane.stream import StreamingPredictor
from stamlane.training.module import StamLaneModule
from tests.cpu_trainer import cpu_trainer

torch.set_num_threads(1)
REPO = Path(__file__).resolve().parents[1]
T, SIZE = 3, (32, 64)
CLIPS = ClipOptions(num_frames=T, stride=2, image_size=SIZE, align="true")  # exact homographies, no ORB
FEATURE = replace(CLIPS, warp="feature")


@pytest.fixture(scope="module")
def root(tiny_synthetic: Callable[..., Path]) -> Path:
    """A tiny synthetic set (160x96, 8 frames a clip): 3 train, 1 val, 1 test clip."""
    return tiny_synthetic(160, 96, 8, train=3, val=1, test=1, challenging=0, seed=3)


def _module(fusion: object = None, **kwargs: object) -> StamLaneModule:
    torch.manual_seed(0)
    return StamLaneModule(
        VGGEncoder(width=0.125),
        fusion or functools.partial(STAM, mode="mixed", order="cs", reduction=4, reading="features"),
        LaneDecoder,
        num_frames=T,
        image_size=SIZE,
        postprocess=PostprocessConfig(min_cluster_pixels=5, min_samples=3),
        **kwargs,
    )


def _calibrate_batchnorm(module: StamLaneModule, clip: torch.Tensor, mats: torch.Tensor) -> None:
    """Set the BatchNorm running statistics from ``clip`` (an untrained net's initial ones shrink the deepest
    stage to ~1e-5, where history hardly reaches the output), then eval mode."""
    for layer in module.modules():
        if isinstance(layer, torch.nn.modules.batchnorm._BatchNorm):
            layer.reset_running_stats()
            layer.momentum = None  # cumulative average
    module.train()
    with torch.no_grad():
        module(clip, mats)
    module.eval()


# --- data ------------------------------------------------------------------------------------------


def test_feature_sample_has_unwarped_frames_and_network_pixel_homographies(root: Path) -> None:
    image = TuSimpleClips(root, "train.json", clip=CLIPS)
    feature = TuSimpleClips(root, "train.json", clip=FEATURE)
    unaligned = TuSimpleClips(root, "train.json", clip=replace(CLIPS, align="none"))
    s_img, s_feat = image[0], feature[0]
    assert NET_HOMOGRAPHIES not in s_img  # image-space data keeps the documented sample unchanged
    mats = s_feat[NET_HOMOGRAPHIES]
    assert mats.shape == (T, 3, 3) and mats.dtype == torch.float32
    assert torch.equal(mats[-1], torch.eye(3))  # the key frame is never resampled
    # the frames are the unwarped ones; the original-pixel alignment is still reported
    torch.testing.assert_close(s_feat["frames"], unaligned[0]["frames"])
    torch.testing.assert_close(s_feat["key_from_hist"], s_img["key_from_hist"])
    assert not torch.allclose(s_feat["frames"][0], s_img["frames"][0], atol=1e-2)  # history differs...
    torch.testing.assert_close(s_feat["frames"][-1], s_img["frames"][-1])  # ...the key frame does not
    net_from_orig = np.asarray(s_feat["meta"]["net_from_orig"])
    expected = net_from_orig @ s_feat["key_from_hist"].double().numpy() @ np.linalg.inv(net_from_orig)
    np.testing.assert_allclose(mats.numpy(), expected / expected[:, 2:3, 2:3], rtol=1e-5, atol=1e-5)
    assert not np.allclose(mats[0].numpy(), np.eye(3), atol=1e-3)  # the camera moved
    # warping the unwarped network frame with the network-pixel homography gives the image-space frame
    oldest = s_feat["frames"][0].permute(1, 2, 0).numpy()
    warped = cv2.warpPerspective(oldest, mats[0].double().numpy(), SIZE[::-1], flags=cv2.INTER_LINEAR)
    target = s_img["frames"][0].permute(1, 2, 0).numpy()
    inside = cv2.warpPerspective(np.ones(SIZE, np.float32), mats[0].double().numpy(), SIZE[::-1]) > 0.999
    inside &= target.sum(-1) > 0
    aligned_err = np.abs(warped - target)[inside].mean()
    unaligned_err = np.abs(oldest - target)[inside].mean()
    print(f"mean abs error inside: aligned {aligned_err:.4f}, unaligned {unaligned_err:.4f}")
    assert aligned_err < 0.5 * unaligned_err, (aligned_err, unaligned_err)


def test_augmented_feature_sample_shares_the_key_frame_geometry(root: Path) -> None:
    transform = ClipTransform(SIZE, crop_scale=(0.7, 0.9), flip_prob=1.0, brightness=0.2)
    image = TuSimpleClips(root, "train.json", clip=CLIPS, transform=transform)
    feature = TuSimpleClips(root, "train.json", clip=FEATURE, transform=transform)
    s_img = image.load(image.entries[1], np.random.default_rng(7))
    s_feat = feature.load(feature.entries[1], np.random.default_rng(7))
    assert s_feat["meta"]["net_from_orig"] == s_img["meta"]["net_from_orig"]
    torch.testing.assert_close(s_feat["frames"][-1], s_img["frames"][-1])
    torch.testing.assert_close(s_feat["binary"], s_img["binary"])
    np.testing.assert_allclose(
        s_feat[NET_HOMOGRAPHIES].numpy(),
        net_homographies(s_img["key_from_hist"].double().numpy(), np.asarray(s_img["meta"]["net_from_orig"])),
        atol=1e-5,
    )


def test_collate_stacks_the_homographies_and_refuses_a_mix(root: Path) -> None:
    feature = TuSimpleClips(root, "train.json", clip=FEATURE)
    image = TuSimpleClips(root, "train.json", clip=CLIPS)
    batch = collate_clips([feature[0], feature[1]])
    assert batch[NET_HOMOGRAPHIES].shape == (2, T, 3, 3)
    assert NET_HOMOGRAPHIES not in collate_clips([image[0], image[1]])
    with pytest.raises(ValueError, match="1 of the 2 samples"):
        collate_clips([feature[0], image[1]])


def test_a_wrong_warp_value_is_a_clear_error(root: Path) -> None:
    with pytest.raises(ValueError, match="'pixels'"):
        ClipDataModule(root=str(root), clip=ClipOptions(warp="pixels"))
    with pytest.raises(ValueError, match="'Feature'"):
        TuSimpleClips(root, "train.json", clip=replace(CLIPS, warp="Feature"))
    with pytest.raises(ValueError, match=r"\(2, 3, 3, 3\).*\(2, 2, 3, 3\)"):
        forward_feature_aligned(_module().net, torch.zeros(2, T, 3, *SIZE), torch.zeros(2, 2, 3, 3))


# --- the module ------------------------------------------------------------------------------------


def test_identity_homographies_give_the_image_path_output() -> None:
    # every frame's features reach the output (an untrained STAM barely passes history on), and batch statistics
    # (train mode) keep the untrained deepest stage from fading to ~1e-5 as it does with initial running stats
    module = _module(SimpleAdd).train()
    torch.manual_seed(1)
    clip = torch.rand(2, T, 3, *SIZE)
    eye = torch.eye(3).expand(2, T, 3, 3).clone()
    near = eye.clone()
    near[:, :-1, 0, 2] = 1e-6  # not exactly the identity: goes through grid_sample
    with torch.no_grad():
        ref = module(clip)
        same = module(clip, eye)
        resampled = module(clip, near)
        moved = module(clip, eye + torch.tensor([[0.0, 0, 9], [0, 0, 5], [0, 0, 0]]))
    for got in (same, resampled):
        torch.testing.assert_close(got[0], ref[0], atol=1e-5, rtol=1e-5)
        torch.testing.assert_close(got[1], ref[1], atol=1e-5, rtol=1e-5)
    assert (moved[0] - ref[0]).abs().max() > 1e-4  # a real motion changes the history features


def test_feature_path_backpropagates_into_the_history_frames() -> None:
    module = _module()
    clip = torch.rand(1, T, 3, *SIZE, requires_grad=True)
    mats = torch.eye(3).expand(1, T, 3, 3).clone()
    mats[0, :-1] = torch.tensor([[1.05, 0.0, -1.0], [0.0, 1.05, 2.0], [0.0, 0.0, 1.0]])
    logits, embedding = module(clip, mats)
    (logits.sum() + embedding.sum()).backward()
    assert clip.grad[0, 0].abs().sum() > 0 and clip.grad[0, -1].abs().sum() > 0


def test_fit_validate_predict_on_feature_warp_data_and_stream_the_result(
    root: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls: list[tuple[int, ...]] = []

    def spy(net, clip, key_from_hist):
        calls.append(tuple(key_from_hist.shape))
        return forward_feature_aligned(net, clip, key_from_hist)

    monkeypatch.setattr(stamlane.training.module, "forward_feature_aligned", spy)
    clip = FEATURE
    data = ClipDataModule(root=str(root), clip=clip, loader=LoaderOptions(batch_size=2), predict_labels=["test.json"])
    module = _module(bf16=True, channels_last=True, report_run_time=False)
    trainer = cpu_trainer(max_steps=3, limit_val_batches=1, check_val_every_n_epoch=None, val_check_interval=3)
    before = [p.detach().clone() for p in module.parameters()]
    trainer.fit(module, datamodule=data)
    assert any(not torch.equal(a, b) for a, b in zip(before, module.parameters()))
    assert len(calls) == 4  # 3 training steps + 1 validation batch
    assert all(shape[1:] == (T, 3, 3) for shape in calls)
    assert np.isfinite(trainer.callback_metrics["val/loss"].item())
    predictions = trainer.predict(module, datamodule=data)
    assert len(calls) == 5 and len(predictions[0]) == 1
    # the streaming predictor takes the trained module as it is and computes what the module computes
    module.bf16 = False  # compared in float32
    sample = TuSimpleClips(root, "test.json", clip=FEATURE)[0]
    frames, mats = sample["frames"], sample[NET_HOMOGRAPHIES]
    _calibrate_batchnorm(module, frames[None], mats[None])
    with torch.no_grad():
        clip_out = module(frames[None], mats[None])
        unaligned = module(frames[None])
    predictor = StreamingPredictor.from_module(module)
    for k in range(T - 1):  # the history frames, cached as they come
        predictor.step(frames[k])
    streamed = predictor.step(frames[-1], mats[:-1].double().numpy())
    torch.testing.assert_close(streamed[0], clip_out[0], atol=1e-4, rtol=1e-4)
    assert (unaligned[0] - clip_out[0]).abs().max() > 1e-2  # the comparison sees the alignment


def test_init_weights_starts_fit_from_a_checkpoint(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Encoder and decoder must fit; another fusion module starts afresh (paper rows from the demo's stage 1)."""
    trained = _module()
    with torch.no_grad():
        for p in trained.parameters():
            p.add_(0.5)
    path = tmp_path / "image_space.ckpt"
    torch.save({"state_dict": trained.state_dict(), "global_step": 7}, path)
    fresh = _module(init_weights=str(path))
    fresh.setup("predict")  # only fit reads the file
    assert not torch.equal(fresh.net.encoder.stages[0][0].weight, trained.net.encoder.stages[0][0].weight)
    fresh.setup("fit")
    for (name, a), b in zip(fresh.state_dict().items(), trained.state_dict().values()):
        assert torch.equal(a, b), name
    with pytest.raises(ValueError, match=r"init_weights: checkpoint .*missing\.ckpt does not exist"):
        _module(init_weights=str(tmp_path / "missing.ckpt")).setup("fit")
    # a shipped model's name, as a config file or a RunSpec gives it: its file is read (and this smaller network
    # does not fit it), where no file of that name is here
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ValueError, match=r"init_weights: 'single-synthetic' does not fit this network"):
        _module(init_weights="single-synthetic").setup("fit")
    # another fusion (no STAM parameters): encoder and decoder loaded, the fusion keeps its own initialisation
    other = _module(fusion=SimpleAdd, init_weights=str(path))
    other.setup("fit")
    loaded = {k: v for k, v in trained.state_dict().items() if not k.startswith("net.fusion.")}
    assert loaded and all(torch.equal(other.state_dict()[k], v) for k, v in loaded.items())
    # a network whose encoder differs does not fit
    wider = StamLaneModule(
        VGGEncoder(width=0.25), SimpleAdd, LaneDecoder, num_frames=T, image_size=SIZE, init_weights=str(path)
    )
    with pytest.raises(ValueError, match="does not fit this network"):
        wider.setup("fit")


@pytest.mark.usefixtures("plain_argv")
def test_cli_fit_and_predict_with_data_warp_feature(
    root: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls = []
    monkeypatch.setattr(
        stamlane.training.module, "forward_feature_aligned", lambda *a: calls.append(1) or forward_feature_aligned(*a)
    )
    common = [
        f"--trainer.default_root_dir={tmp_path}",
        "--trainer.enable_progress_bar=false",
        "--trainer.enable_model_summary=false",
    ]
    fit = [
        "fit",
        "--config",
        str(REPO / "configs" / "demo_feature_warp.yaml"),
        f"--data.root={root}",
        "--data.clip.num_frames=2",
        "--data.clip.image_size=[32, 64]",
        "--data.loader.batch_size=3",
        "--data.loader.num_workers=0",
        "--data.clip.align=true",
        "--model.encoder.width=0.125",
        f"--trainer.logger.save_dir={tmp_path}",
        "--trainer.max_steps=2",
        "--trainer.val_check_interval=2",
        f"--predictions.output_dir={tmp_path / 'predictions'}",
        *common,
    ]
    assert cli_main(fit) == 0
    assert len(calls) == 3  # 2 training steps + 1 validation batch, all in feature space
    version = next(tmp_path.rglob("version_0"))
    ckpt = version / "checkpoints" / "last.ckpt"
    config = str(version / "config.yaml")
    out = tmp_path / "folder"
    frames = root / "clips" / "val-0000"
    predict = ["predict", "--config", config, f"--ckpt_path={ckpt}", "--trainer.logger=false", *common]
    assert cli_main([*predict, f"--predictions.output_dir={out}", f"--source={frames}", "--data.clip.align=none"]) == 0
    assert len(calls) == 6  # the folder's 8 clips in batches of 3: 3 more batches, in feature space too
    assert len(list((out / "lines").iterdir())) == 8
    # fine-tuning: a new fit that starts from the checkpoint's weights
    tuned = tmp_path / "tuned"
    finetune = [*fit, f"--model.init_weights={ckpt}", "--trainer.max_steps=1", f"--trainer.logger.save_dir={tuned}"]
    assert cli_main(finetune) == 0
    assert torch.load(next(tuned.rglob("last.ckpt")), weights_only=True)["global_step"] == 1
