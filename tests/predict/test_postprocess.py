"""stamlane.predict.postprocess: DBSCAN on embeddings, nearest-centre assignment, robust fit, original pixels."""

from __future__ import annotations

import numpy as np
import pytest

from stamlane.predict.postprocess import PostprocessConfig, cluster_lane_pixels, decode_lanes, fit_lane

H, W = 128, 256


def _heads(xs_at_bottom: list[float], spread: float = 0.2, seed: int = 0) -> tuple[np.ndarray, np.ndarray, list]:
    """Lane probability (H, W) and embeddings (4, H, W) of straight lanes converging to (W/2, 40).

    Returns the true lanes as functions y -> x (network pixels) too.
    """
    rng = np.random.default_rng(seed)
    prob = np.full((H, W), 0.1, dtype=np.float32)
    emb = rng.normal(0.0, 1.0, size=(4, H, W)).astype(np.float32)
    truth = []
    for i, xb in enumerate(xs_at_bottom):
        mean = np.zeros(4, dtype=np.float32)
        mean[i % 4] = 3.0 if i < 4 else -3.0

        def x_of(y: float, xb: float = xb) -> float:
            return W / 2 + (xb - W / 2) * (y - 40) / (H - 1 - 40)

        for y in range(50, H):
            xc = x_of(y)
            x0, x1 = round(xc) - 1, round(xc) + 2
            prob[y, x0:x1] = 0.95
            emb[:, y, x0:x1] = mean[:, None] + rng.normal(0.0, spread, size=(4, x1 - x0))
        truth.append(x_of)
    return prob, emb, truth


def test_cluster_labels_known_clusters() -> None:
    rng = np.random.default_rng(1)
    means = np.array([[0, 0, 0, 0], [3, 0, 0, 0], [0, 3, 0, 0]], dtype=np.float32)
    sizes = [600, 300, 100]
    emb = np.concatenate([m + rng.normal(0, 0.15, size=(n, 4)) for m, n in zip(means, sizes)]).astype(np.float32)
    labels = cluster_lane_pixels(emb, PostprocessConfig(max_points=400))
    truth = np.repeat([0, 1, 2], sizes)  # clusters are numbered largest first
    assert (labels == truth).mean() > 0.99


def test_cluster_far_points_are_noise_and_few_points_give_nothing() -> None:
    rng = np.random.default_rng(2)
    emb = np.concatenate([rng.normal(0, 0.1, size=(200, 4)), [[20.0, 20.0, 20.0, 20.0]]]).astype(np.float32)
    labels = cluster_lane_pixels(emb, PostprocessConfig())
    assert labels[-1] == -1 and (labels[:-1] == 0).all()
    assert (cluster_lane_pixels(emb[:3], PostprocessConfig()) == -1).all()


def test_decode_recovers_lanes_in_original_pixels() -> None:
    prob, emb, truth = _heads([40.0, 110.0, 160.0, 230.0])
    # network input = original image (1280x720, top 200 rows cropped) scaled to 256x128
    sx, sy, crop = 1280 / W, (720 - 200) / H, 200
    orig_from_net = np.array([[sx, 0, 0], [0, sy, crop], [0, 0, 1]])
    h_samples = list(range(160, 720, 10))
    lanes = decode_lanes(prob, emb, orig_from_net, y_samples=h_samples, orig_size=(720, 1280))
    assert len(lanes) == 4
    for lane, x_of in zip(lanes, truth):  # left to right
        assert lane.shape[1] == 2
        assert set(lane[:, 1].astype(int)) <= set(h_samples)
        assert lane[:, 1].min() <= 200 + 55 * sy and lane[:, 1].max() >= 700
        expected = np.array([x_of((y - crop) / sy) * sx for y in lane[:, 1]])
        assert np.abs(lane[:, 0] - expected).max() < 0.6 * sx  # within a network pixel or so


def test_decode_drops_small_clusters_and_is_deterministic() -> None:
    prob, emb, _ = _heads([60.0, 200.0])
    # a 6-pixel blob with its own embedding: lane probability high but too small to be a lane
    prob[100:102, 10:13] = 0.99
    emb[:, 100:102, 10:13] = np.array([0, 0, -3.0, 0], dtype=np.float32)[:, None, None]
    config = PostprocessConfig(min_samples=3)
    lanes = decode_lanes(prob, emb, config=config)
    assert len(lanes) == 2
    again = decode_lanes(prob, emb, config=config)
    assert all(np.array_equal(a, b) for a, b in zip(lanes, again))
    # default sampling: every y_step px on multiples of it
    assert np.all(lanes[0][:, 1] % 10 == 0) and np.all(np.diff(lanes[0][:, 1]) == 10)


def test_fit_lane_rejects_outliers() -> None:
    ys = np.arange(100, 400, 2.0)
    xs = 0.5 * ys + 20
    xs[::15] += 80  # gross outliers in some bands
    pts = np.stack([xs, ys], 1)
    lane = fit_lane(pts[np.argsort(-ys)], PostprocessConfig(degree=2))
    assert lane is not None
    assert np.abs(lane[:, 0] - (0.5 * lane[:, 1] + 20)).max() < 1.0
    assert fit_lane(np.array([[5.0, 3.0], [6.0, 4.0]]), PostprocessConfig()) is None  # one band only


def test_empty_and_bad_inputs() -> None:
    assert decode_lanes(np.zeros((H, W)), np.zeros((4, H, W))) == []
    with pytest.raises(ValueError, match=r"expected embedding of shape \(E, 128, 256\)"):
        decode_lanes(np.zeros((H, W)), np.zeros((4, H, W + 1)))
    with pytest.raises(ValueError, match="orig_from_net"):
        decode_lanes(np.zeros((H, W)), np.zeros((4, H, W)), np.eye(2))
    with pytest.raises(ValueError, match="prob_thresh must be in"):
        PostprocessConfig(prob_thresh=1.5)


def test_a_network_never_that_sure_still_gets_its_lanes() -> None:
    """Lane probabilities topping out at 0.8 (a weakly trained network; measured 0.79-0.86 on one ablation run)
    leave no pixel above cluster_thresh 0.9: clustering falls back to every lane pixel instead of no lane."""
    prob, emb, _ = _heads([40.0, 110.0, 160.0, 230.0])
    prob = np.where(prob > 0.5, 0.8, prob).astype(np.float32)
    assert len(decode_lanes(prob, emb, np.eye(3), orig_size=(H, W))) == 4
    assert decode_lanes(prob, emb, np.eye(3), PostprocessConfig(prob_thresh=0.85, cluster_thresh=0.9)) == []


def test_extend_continues_a_lane_hidden_at_its_far_end_to_the_common_top() -> None:
    prob, emb, truth = _heads([40.0, 110.0, 160.0, 230.0])
    for y in range(50, 90):  # a vehicle hides the far part of the second lane
        x = round(truth[1](y))
        prob[y, x - 1 : x + 2] = 0.1
    y_samples = list(range(50, H, 4))
    plain = decode_lanes(prob, emb, None, PostprocessConfig(degree=1), y_samples=y_samples, orig_size=(H, W))
    extended = decode_lanes(
        prob, emb, None, PostprocessConfig(degree=1, extend=True), y_samples=y_samples, orig_size=(H, W)
    )
    assert len(plain) == len(extended) == 4
    tops = [lane[:, 1].min() for lane in plain]
    assert tops[1] >= 90 and max(tops[0], tops[2], tops[3]) <= 58  # without extend the hidden lane ends early
    for lane, x_of in zip(extended, truth):
        assert lane[:, 1].min() == min(tops) and lane[:, 1].max() == y_samples[-1]
        np.testing.assert_allclose(lane[:, 0], [x_of(y) for y in lane[:, 1]], atol=1.5)  # along the straight lane


def test_a_curve_continues_along_its_end_tangents() -> None:
    from stamlane.predict.postprocess import LaneCurve

    curve = LaneCurve(np.array([0.01, 0.0, 5.0]), y_lo=10.0, y_hi=20.0)  # x = 0.01 y^2 + 5
    np.testing.assert_allclose(curve.x_at(np.array([15.0])), [0.01 * 225 + 5])
    # below y_lo: x(10) + x'(10) (y - 10) with x'(10) = 0.2; above y_hi: x(20) + 0.4 (y - 20)
    np.testing.assert_allclose(curve.x_at(np.array([0.0, 30.0])), [6.0 - 2.0, 9.0 + 4.0])


def test_dbscan_gives_sklearns_labels() -> None:
    from sklearn.cluster import DBSCAN

    from stamlane.predict.postprocess import dbscan

    rng = np.random.default_rng(1)
    for _ in range(150):  # tight and loose clusters, bridges, duplicates, every core count from 2 to 40
        n, spread, min_samples = int(rng.integers(20, 700)), float(rng.uniform(0.03, 0.5)), int(rng.integers(2, 40))
        centres = rng.normal(size=(int(rng.integers(1, 7)), 4)) * 1.2
        points = centres[rng.integers(0, len(centres), n)] + rng.normal(scale=spread, size=(n, 4))
        points[: n // 10] = points[n // 10 : 2 * (n // 10)]  # duplicates: neighbours at distance 0
        points = points.astype(np.float32)
        expected = DBSCAN(eps=0.35, min_samples=min_samples, algorithm="ball_tree").fit_predict(points)
        assert np.array_equal(dbscan(points, 0.35, min_samples), expected)


@pytest.mark.parametrize("name", ["stam4-synthetic", "single-synthetic"])
def test_the_shipped_models_lanes_are_the_same_as_with_sklearns_dbscan(
    name: str, synthetic_root, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The lanes the shipped models' own outputs decode to, with `dbscan` and with sklearn's estimator."""
    import torch

    from stamlane.data.collate import collate_clips
    from stamlane.data.layouts import make_clips
    from stamlane.data.options import ClipOptions
    from stamlane.predict import postprocess
    from stamlane.training.module import StamLaneModule
    from stamlane.weights import shipped_path

    module = StamLaneModule.from_checkpoint(shipped_path(name)).eval()
    clip = ClipOptions(num_frames=module.num_frames, image_size=(80, 256), crop_top=0.4, align="fly")
    files = ["test.json", "challenging.json"]
    samples = [s for f in files for s in make_clips("tusimple", synthetic_root, [f], clip=clip)]
    with torch.no_grad():
        logits, embedding = module._run(collate_clips(samples))
    metas = [s["meta"] for s in samples]
    lanes = module.decode(logits, embedding, metas)
    monkeypatch.setattr(postprocess, "_dbscan_inner", None)  # sklearn's DBSCAN estimator
    assert sum(len(image) for image in lanes) > 0
    expected = module.decode(logits, embedding, metas)
    assert len(lanes) == len(expected) == len(samples)
    for got, want in zip(lanes, expected):
        assert len(got) == len(want) and all(np.array_equal(a, b) for a, b in zip(got, want))


# ---------------------------------------------------------------------------------- pixel counts and the input size
def _road(h: int, w: int, factor: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Two straight lanes and a 24x2-pixel streak with its own embedding on an ``h`` x ``w`` map, each network pixel
    repeated ``factor`` x ``factor`` times: the same road at ``factor`` times the input size."""
    rng = np.random.default_rng(3)
    prob = np.full((h, w), 0.05, dtype=np.float32)
    emb = rng.normal(0.0, 1.0, size=(4, h, w)).astype(np.float32)
    for i, xb in enumerate((0.2 * w, 0.8 * w)):
        for y in range(h // 4, h):
            x = round(w / 2 + (xb - w / 2) * (y - h // 4) / (h - 1 - h // 4))
            prob[y, x - 1 : x + 2] = 0.97
            emb[:, y, x - 1 : x + 2] = (3.0 * np.eye(4)[i])[:, None] + rng.normal(0, 0.05, (4, 3))
    prob[h // 2 : h // 2 + 24, 5:7] = 0.97  # 48 pixels over three bands of rows: a cluster below min_cluster_pixels 50
    emb[:, h // 2 : h // 2 + 24, 5:7] = np.array([0, 0, -3.0, 0], np.float32)[:, None, None]
    big_prob = np.kron(prob, np.ones((factor, factor), np.float32))
    big_emb = np.stack([np.kron(e, np.ones((factor, factor), np.float32)) for e in emb])
    return big_prob, big_emb


def test_pixel_counts_are_unchanged_at_the_reference_size() -> None:
    config, plain = PostprocessConfig(), PostprocessConfig(reference_size=None)
    assert config.reference_size == (80, 256) and config.pixel_scale((80, 256)) == 1.0
    assert config.min_pixels(1.0) == 50 and config.core_samples(1234, 1.0) == 25
    prob, emb = _road(80, 256)
    assert prob.shape == (80, 256)
    got, want = decode_lanes(prob, emb, config=config), decode_lanes(prob, emb, config=plain)
    assert len(got) == len(want) == 2  # the streak dropped
    assert len(decode_lanes(prob, emb, config=PostprocessConfig(min_cluster_pixels=30))) == 3  # for its size alone
    assert all(np.array_equal(a, b) for a, b in zip(got, want))


def test_pixel_counts_scale_with_the_area_of_the_map() -> None:
    config = PostprocessConfig()
    assert config.pixel_scale((160, 512)) == 4.0 and config.pixel_scale((40, 128)) == 0.25
    assert PostprocessConfig(reference_size=None).pixel_scale((160, 512)) == 1.0
    assert config.min_pixels(4.0) == 200 and config.min_pixels(0.01) == 1
    # min_samples: the subsample drawn against the one the reference size would draw (max_points 2000)
    assert config.core_samples(4000, 4.0) == 50  # 2000 drawn, 1000 at 80x256: twice as dense
    assert config.core_samples(12000, 4.0) == 25  # both subsamples full: the same density
    assert config.core_samples(250, 0.25) == 6  # 250 drawn, 1000 at 80x256


def test_the_same_road_at_twice_the_input_decodes_to_the_same_lanes() -> None:
    """At 160x512 the streak covers 192 pixels: an extra lane with the counts as given at 80x256, dropped with them
    scaled to the map (200)."""
    prob, emb = _road(80, 256, factor=2)
    assert prob.shape == (160, 512)
    scaled = decode_lanes(prob, emb, config=PostprocessConfig(max_points=10_000))
    as_given = decode_lanes(prob, emb, config=PostprocessConfig(max_points=10_000, reference_size=None))
    assert len(scaled) == 2 and len(as_given) == 3
    small = decode_lanes(*_road(80, 256), config=PostprocessConfig(max_points=10_000))
    for big, one in zip(scaled, small):  # the same lanes, in the map's pixels (2x)
        np.testing.assert_allclose(np.interp(one[:, 1] * 2, big[:, 1], big[:, 0]), one[:, 0] * 2, atol=2.0)


def test_the_reference_size_is_checked_and_taken_from_a_list() -> None:
    assert PostprocessConfig(reference_size=[96, 320]).reference_size == (96, 320)  # type: ignore[arg-type]
    for bad in ((80,), (0, 256), (80.5, 256), (True, 256)):
        with pytest.raises(ValueError, match="reference_size must be"):
            PostprocessConfig(reference_size=bad)  # type: ignore[arg-type]


def test_the_same_road_at_the_paper_size_decodes_to_the_same_lanes() -> None:
    """256x512, the paper's input: 3.2x the rows and 2x the columns of 80x256 (no whole factor). The streak's 48
    pixels become 307: drawn as a lane with the counts as given, dropped with them scaled to the map's area (6.4x)."""
    import cv2

    prob, emb = _road(80, 256)
    big_prob = cv2.resize(prob, (512, 256), interpolation=cv2.INTER_NEAREST)
    big_emb = np.stack([cv2.resize(e, (512, 256), interpolation=cv2.INTER_NEAREST) for e in emb])
    sx, sy = 256 / 512, 80 / 256  # the big map's pixels -> the small map's (pixel centres at integers, as
    to_small = np.array([[sx, 0, 0.5 * sx - 0.5], [0, sy, 0.5 * sy - 0.5], [0, 0, 1.0]])  # data/transforms.py)
    rows = list(range(24, 80, 4))
    small = decode_lanes(prob, emb, config=PostprocessConfig(max_points=10_000), orig_size=(80, 256), y_samples=rows)
    scaled = decode_lanes(big_prob, big_emb, to_small, PostprocessConfig(max_points=10_000), rows, (80, 256))
    plain = PostprocessConfig(max_points=10_000, reference_size=None)
    assert (
        len(small) == len(scaled) == 2 and len(decode_lanes(big_prob, big_emb, to_small, plain, rows, (80, 256))) == 3
    )
    for big, one in zip(scaled, small):  # the same lanes in the same (small map's) pixels, to half a pixel: the
        # nearest-neighbour resize at 3.2x repeats rows 3 or 4 times (0.48 here; 1.04 without the centres' offset)
        np.testing.assert_allclose(np.interp(one[:, 1], big[:, 1], big[:, 0]), one[:, 0], atol=0.75)
