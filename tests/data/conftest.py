"""Fixtures of the data tests: small files in every layout, written by the tests themselves."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

W, H = 96, 64
"""Size of the hand-made test images (original pixels)."""


def write_image(path: Path, value: int = 100, lanes: list[np.ndarray] | None = None) -> None:
    """A grey image with optional bright lanes drawn on it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    img = np.full((H, W, 3), value, np.uint8)
    img[:, :, 1] = (np.arange(W) * 2 % 256).astype(np.uint8)[None, :]  # some texture
    for lane in lanes or []:
        cv2.polylines(img, [np.round(lane).astype(np.int32)], False, (255, 255, 255), 1)
    cv2.imwrite(str(path), img)


@pytest.fixture
def tusimple_root(tmp_path: Path) -> Path:
    """TuSimple layout: clips/0313-1/<id>/1..20.jpg and a label json-lines file for frame 20."""
    h_samples = list(range(20, 64, 10))
    records = []
    for clip in ("100", "200"):
        for n in range(1, 21):
            write_image(tmp_path / "clips" / "0313-1" / clip / f"{n}.jpg", value=5 * n)
        records.append(
            {
                "raw_file": f"clips/0313-1/{clip}/20.jpg",
                "lanes": [[60, 65, 70, 75, 80], [30, 25, -2, 15, 10], [-2, -2, -2, -2, -2]],
                "h_samples": h_samples,
            }
        )
    (tmp_path / "label_data.json").write_text("".join(json.dumps(r) + "\n" for r in records))
    return tmp_path


@pytest.fixture
def culane_root(tmp_path: Path) -> Path:
    """CULane layout: driver_x/<video>.MP4/00000.jpg, 00030.jpg, ... with .lines.txt beside, and a list file."""
    video = tmp_path / "driver_23_30frame" / "05151649_0422.MP4"
    for n in range(0, 120, 30):
        write_image(video / f"{n:05d}.jpg", value=20 + n)
        (video / f"{n:05d}.lines.txt").write_text("10.5 60 20.5 40 30.5 20 \n80 60 70 40 60 20 \n")
    (tmp_path / "list").mkdir()
    (tmp_path / "list" / "train_gt.txt").write_text(
        "/driver_23_30frame/05151649_0422.MP4/00090.jpg /laneseg_label_w16/x.png 1 1 0 0\n"
        "/driver_23_30frame/05151649_0422.MP4/00060.jpg /laneseg_label_w16/y.png 1 1 0 0\n"
    )
    return tmp_path


@pytest.fixture
def apollo_root(tmp_path: Path) -> Path:
    """ApolloScape sequence with timestamp names and .lines.txt labels mirrored under labels/."""
    rel = Path("ColorImage_road02/ColorImage/Record001/Camera 5")
    stamps = ["170927_063811892", "170927_063812021", "170927_063812150", "170927_063812279"]
    for i, s in enumerate(stamps):
        write_image(tmp_path / rel / f"{s}_Camera_5.jpg", value=30 * (i + 1))
        label = tmp_path / "labels" / rel / f"{s}_Camera_5.lines.txt"
        label.parent.mkdir(parents=True, exist_ok=True)
        label.write_text("5 60 15 30 25 10\n")
    (tmp_path / "test.txt").write_text(f"{rel / (stamps[-1] + '_Camera_5.jpg')}\n")
    return tmp_path


@pytest.fixture
def vil_root(tmp_path: Path) -> Path:
    """VIL-100 layout: JPEGImages/<video>/<frame>.jpg + Json/<video>/<frame>.jpg.json, data/ lists."""
    video = "0_Road014_Trim005_frames"
    for n in range(6):
        name = f"{n:05d}.jpg"
        write_image(tmp_path / "JPEGImages" / video / name, value=40 + 10 * n)
        ann = {
            "info": {"image_path": name, "height": H, "width": W},
            "annotations": {
                "lane": [
                    {"lane_id": 2, "attribute": 1, "points": [[70, 60], [60, 30], [55, 15]]},
                    {"lane_id": 1, "attribute": 1, "points": [[10, 60], [30, 30], [40, 15]]},
                ]
            },
        }
        path = tmp_path / "Json" / video / f"{name}.json"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(ann))
    (tmp_path / "data").mkdir()
    (tmp_path / "data" / "train.txt").write_text(
        f"/JPEGImages/{video}/00005.jpg /Annotations/{video}/00005.png\n/JPEGImages/{video}/00003.jpg\n"
    )
    return tmp_path
