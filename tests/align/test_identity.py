"""The identities of a frame (`stamlane.align.identity`): its pixels' digest names what the estimator read, its
file's digest the bytes before any decoding; each changes with what it reads and with nothing else."""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np

from stamlane.align.identity import file_identity, frame_digest


def test_the_pixel_digest_is_of_the_pixels_whatever_the_file(tmp_path: Path) -> None:
    image = np.random.default_rng(0).integers(0, 256, (24, 32, 3), dtype=np.uint8)
    png, bmp = tmp_path / "1.png", tmp_path / "1.bmp"
    cv2.imwrite(str(png), image)
    cv2.imwrite(str(bmp), image)
    decoded = [cv2.imread(str(p)) for p in (png, bmp)]
    assert frame_digest(decoded[0]) == frame_digest(decoded[1]) == frame_digest(image.copy())
    assert file_identity(png) != file_identity(bmp)  # other bytes, the same picture
    changed = image.copy()
    changed[0, 0, 0] ^= 1
    assert frame_digest(changed) != frame_digest(image)
    assert frame_digest(image[:, :, 0]) != frame_digest(image[:, :, :1])  # the shape is in the digest


def test_the_file_identity_is_of_the_bytes_wherever_they_lie(tmp_path: Path) -> None:
    first = tmp_path / "a" / "1.jpg"
    first.parent.mkdir()
    first.write_bytes(b"\xff\xd8 some bytes \xff\xd9")
    copy = tmp_path / "2.jpg"
    copy.write_bytes(first.read_bytes())
    assert file_identity(first) == file_identity(copy) is not None
    copy.write_bytes(b"\xff\xd8 other bytes \xff\xd9")
    assert file_identity(copy) != file_identity(first)
    assert file_identity(tmp_path / "missing.jpg") is None and file_identity(tmp_path / "a") is None
    os.mkfifo(tmp_path / "fifo.jpg")
    assert file_identity(tmp_path / "fifo.jpg") is None  # not a regular file: not read, no wait for a writer
