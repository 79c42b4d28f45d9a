"""stamlane.safety.images: a truncated frame is unreadable everywhere (datasets, align), never a grey picture."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from stamlane.safety.images import read_image


def _picture() -> np.ndarray:
    rng = np.random.default_rng(0)
    return rng.integers(0, 255, (48, 64, 3), dtype=np.uint8)


@pytest.mark.parametrize("suffix", [".jpg", ".png"])
def test_whole_files_read_and_truncated_ones_do_not(tmp_path: Path, suffix: str) -> None:
    path = tmp_path / f"f{suffix}"
    cv2.imwrite(str(path), _picture())
    image = read_image(path)
    assert image is not None and image.shape == (48, 64, 3)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) * 2 // 3])
    assert cv2.imread(str(path)) is not None or suffix == ".png"  # OpenCV alone accepts the cut JPEG (grey)
    assert read_image(path) is None
    path.write_bytes(b"")
    assert read_image(path) is None
    assert read_image(tmp_path / "missing.jpg") is None


def test_a_truncated_key_frame_is_a_data_error_and_align_says_so(tiny_synthetic, tmp_path: Path, capsys) -> None:
    from stamlane.align.cli import main as align
    from stamlane.data.clips import TuSimpleClips
    from stamlane.data.labels import DataError
    from stamlane.data.options import ClipOptions

    root = tiny_synthetic(96, 64, 4, train=1, val=0, test=0, challenging=0, seed=2)
    key = root / json.loads((root / "train.json").read_text().splitlines()[0])["raw_file"]
    key.write_bytes(key.read_bytes()[:-200])
    with pytest.raises(DataError, match="missing, truncated or not an image"):
        TuSimpleClips(root, "train.json", clip=ClipOptions(image_size=(32, 64), align="none"))[0]
    assert align([str(root), "--cache", str(tmp_path / "cache"), "--num-frames", "2", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert f"cannot read frame {key}" in err and len(err.splitlines()) == 1
    assert list((tmp_path / "cache").rglob("*.json"))  # the readable pairs were still cached
