"""Feature-space warping: identity, translations by whole cells, agreement with image-space warping."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import torch
import torch.nn.functional as F

from stamlane.models.feature_warp import feat_from_net, feature_homography, sampling_grid, warp_features

torch.set_num_threads(1)


def _translation(dx: float, dy: float) -> np.ndarray:
    return np.array([[1.0, 0.0, dx], [0.0, 1.0, dy], [0.0, 0.0, 1.0]])


def test_feat_from_net_maps_pixel_centres_to_cell_centres() -> None:
    m = feat_from_net(4)
    # network pixels 0..3 form cell 0, whose centre is pixel 1.5
    centre = m @ np.array([1.5, 1.5, 1.0])
    np.testing.assert_allclose(centre, [0.0, 0.0, 1.0])
    np.testing.assert_allclose(m @ np.array([5.5, 9.5, 1.0]), [1.0, 2.0, 1.0])


def test_identity_returns_the_features() -> None:
    feats = torch.randn(3, 5, 6, 7)
    out = warp_features(feats, np.eye(3), stride=16)
    assert out.shape == feats.shape and out.dtype == feats.dtype
    torch.testing.assert_close(out, feats, atol=1e-6, rtol=0)


@pytest.mark.parametrize(("kx", "ky"), [(1, 0), (-2, 1), (0, -3)])
def test_translation_by_whole_cells_shifts_features(kx: int, ky: int) -> None:
    stride = 8
    feats = torch.randn(2, 4, 6, 9)
    out = warp_features(feats, _translation(kx * stride, ky * stride), stride)
    # key cell (y, x) sees history cell (y - ky, x - kx); cells with no source are zeros
    expected = torch.zeros_like(feats)
    h, w = feats.shape[-2:]
    ys, yd = (slice(0, h - ky), slice(ky, h)) if ky >= 0 else (slice(-ky, h), slice(0, h + ky))
    xs, xd = (slice(0, w - kx), slice(kx, w)) if kx >= 0 else (slice(-kx, w), slice(0, w + kx))
    expected[..., yd, xd] = feats[..., ys, xs]
    torch.testing.assert_close(out, expected, atol=1e-5, rtol=0)


def test_original_pixels_are_converted_with_net_from_orig() -> None:
    # a 2x downscale: a shift of 32 original pixels is 16 network pixels = 2 cells of stride 8
    net_from_orig = np.array([[0.5, 0, -0.25], [0, 0.5, -0.25], [0, 0, 1.0]])
    feats = torch.randn(1, 3, 5, 8)
    via_orig = warp_features(feats, _translation(32, 0), 8, net_from_orig=net_from_orig)
    via_net = warp_features(feats, _translation(16, 0), 8)
    torch.testing.assert_close(via_orig, via_net, atol=1e-6, rtol=0)
    torch.testing.assert_close(via_net[..., 2:], feats[..., :-2], atol=1e-5, rtol=0)


def test_batch_of_homographies_each_applied_to_its_map() -> None:
    feats = torch.randn(2, 3, 4, 6)
    hs = np.stack([np.eye(3), _translation(4, 0)])
    out = warp_features(feats, torch.from_numpy(hs), stride=4)
    torch.testing.assert_close(out[0], feats[0], atol=1e-6, rtol=0)
    torch.testing.assert_close(out[1, ..., 1:], feats[1, ..., :-1], atol=1e-5, rtol=0)
    assert out[1, ..., 0].abs().max() < 1e-5  # no source: zeros (up to rounding of the sampling position)


def test_bfloat16_features_keep_their_dtype_and_positions() -> None:
    feats = torch.randn(1, 2, 4, 6).to(torch.bfloat16)
    out = warp_features(feats, _translation(16, 0), 16)
    assert out.dtype == torch.bfloat16
    torch.testing.assert_close(out[..., 1:], feats[..., :-1], atol=0, rtol=0)


def test_agrees_with_warping_the_image_then_encoding() -> None:
    """A smooth image, an average-pooling 'encoder' of stride 8, a mild ground-plane-like homography."""
    stride, height, width = 8, 96, 192
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float64)
    image = (np.sin(xx / 23.0) + np.cos(yy / 17.0) + 0.01 * xx).astype(np.float32)  # varies slowly per cell
    key_from_hist = np.array([[1.02, 0.03, 5.0], [0.01, 1.03, 3.0], [0.0, 1e-4, 1.0]])

    def encode(img: np.ndarray) -> torch.Tensor:
        return F.avg_pool2d(torch.from_numpy(img)[None, None], stride)

    warped_image = cv2.warpPerspective(image, key_from_hist, (width, height), flags=cv2.INTER_LINEAR)
    image_space = encode(warped_image)
    feature_space = warp_features(encode(image), key_from_hist, stride)
    # compare cells whose source lies well inside the history frame (borders differ by construction)
    inner = (slice(None), slice(None), slice(1, -2), slice(1, -2))
    diff = (image_space - feature_space)[inner].abs()
    spread = image_space[inner].std()
    assert diff.max() < 0.1 * spread, (diff.max(), spread)
    # and a wrong homography (one cell off) disagrees clearly, so the check can fail
    wrong = warp_features(encode(image), _translation(stride, 0) @ key_from_hist, stride)
    assert (image_space - wrong)[inner].abs().max() > 3 * diff.max()


def test_sampling_grid_behind_the_camera_is_outside() -> None:
    # a homography that sends part of the key grid to w <= 0 in the history frame
    h = torch.tensor([[[1.0, 0, 0], [0, 1.0, 0], [0, -0.5, 1.0]]], dtype=torch.float64)
    grid = sampling_grid(torch.linalg.inv(h), (6, 4))
    assert grid.shape == (1, 6, 4, 2)
    assert torch.isfinite(grid).all()
    assert (grid[0, 2:] == -4.0).all()  # rows y >= 2 have 1 - 0.5 y <= 0


def test_feature_homography_is_conjugated_to_the_grid() -> None:
    h = feature_homography(_translation(16, -32), stride=16)
    np.testing.assert_allclose(h[0].numpy(), _translation(1, -2), atol=1e-12)


@pytest.mark.parametrize(
    ("feats", "matrix", "stride", "match"),
    [
        (torch.zeros(2, 3, 4), np.eye(3), 16, "feats of shape"),
        (torch.zeros(2, 3, 4, 4), np.eye(4), 16, "key_from_hist must be"),
        (torch.zeros(2, 3, 4, 4), np.stack([np.eye(3)] * 3), 16, "1 or 2 homographies"),
        (torch.zeros(1, 3, 4, 4), np.full((3, 3), np.nan), 16, "finite"),
        (torch.zeros(1, 3, 4, 4), np.zeros((3, 3)), 16, "singular|zero"),
        (torch.zeros(1, 3, 4, 4), np.eye(3), 0, "stride must be"),
    ],
)
def test_bad_inputs_raise(feats: torch.Tensor, matrix: np.ndarray, stride: int, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        warp_features(feats, matrix, stride)


def test_bad_net_from_orig_raises() -> None:
    with pytest.raises(ValueError, match="net_from_orig is singular"):
        warp_features(torch.zeros(1, 1, 2, 2), np.eye(3), 4, net_from_orig=np.zeros((3, 3)))
