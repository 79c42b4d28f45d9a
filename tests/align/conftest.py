"""Synthetic road frames with a known ground homography, shared by the align tests."""

from __future__ import annotations

import numpy as np
import pytest

from stamlane.align.egomotion import RoadCamera
from stamlane.align.synthetic import road_texture

# a 640x360 camera keeps the tests fast; same geometry as the benchmark's 1280x720 one, halved
SMALL_CAMERA = RoadCamera(width=640, height=360, focal=500.0, horizon_row=140.0, camera_height=1.5)
SMALL_HORIZON = 162  # 0.45 * 360


@pytest.fixture(scope="session")
def texture() -> np.ndarray:
    return road_texture(seed=7, texture=0.6)


def corner_error(estimate: np.ndarray, truth: np.ndarray, shape: tuple[int, int], horizon_row: int) -> float:
    """Mean distance (key pixels) of the key frame's ground corners sent to the history frame and back."""
    height, width = shape
    corners = np.array(
        [[0, horizon_row, 1], [width - 1, horizon_row, 1], [width - 1, height - 1, 1], [0, height - 1, 1]], float
    )
    hist = corners @ np.linalg.inv(truth).T
    back = hist @ np.asarray(estimate).T
    back = back[:, :2] / back[:, 2:]
    return float(np.linalg.norm(back - corners[:, :2], axis=1).mean())
