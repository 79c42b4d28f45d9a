"""Reading frames: a truncated file is unreadable, not a grey picture.

``cv2.imread`` decodes a JPEG cut short into a full-size image whose missing part is grey (it only prints a
warning), so a broken download would train and score silently. `read_image` checks that a JPEG ends with its
end-of-image marker and a PNG with its ``IEND`` chunk before decoding.
"""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np

__all__ = ["read_image"]

_JPEG_END = b"\xff\xd9"
_PNG_END = b"IEND"


def read_image(path: str | os.PathLike) -> np.ndarray | None:
    """The image as BGR uint8 ``(H, W, 3)``, or ``None`` when it is missing, truncated or not an image."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError:
        return None
    suffix = path.suffix.lower()
    if suffix in (".jpg", ".jpeg") and not data.rstrip(b"\x00").endswith(_JPEG_END):
        return None
    if suffix == ".png" and _PNG_END not in data[-16:]:
        return None
    if not data:
        return None
    return cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
