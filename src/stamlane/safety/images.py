"""Reading frames: a truncated file is unreadable, not a grey picture; a hostile one costs bounded memory.

``cv2.imread`` decodes a JPEG cut short into a full-size image whose missing part is grey (it only prints a
warning), so a broken download would train and score silently. `read_image` checks that a JPEG ends with its
end-of-image marker and a PNG with its ``IEND`` chunk before decoding.

A decompression bomb (a few KiB of PNG declaring 100,000 x 100,000 pixels) would make the decoder allocate the
declared size: the PNG and JPEG headers are read first and an image over `MAX_IMAGE_PIXELS` or with a side over
``stamlane_eval.io.MAX_IMAGE_SIDE`` is refused before decoding (other formats are left to OpenCV's own limit).
A FIFO, a device or a directory named as a frame is refused without being read.
"""

from __future__ import annotations

import os
import stat
import struct
from pathlib import Path

import cv2
import numpy as np
from stamlane_eval.io import MAX_IMAGE_SIDE

__all__ = ["MAX_IMAGE_BYTES", "MAX_IMAGE_PIXELS", "declared_size", "open_video", "read_image"]

MAX_IMAGE_PIXELS = 1 << 26
"""Most pixels in one frame (67 Mpx, twice 8K UHD): 192 MiB decoded as BGR."""
MAX_IMAGE_BYTES = 256 << 20
"""Largest image file read (256 MiB)."""

_JPEG_END = b"\xff\xd9"
_PNG_END = b"IEND"
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_JPEG_SOF = {0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF}


def declared_size(data: bytes) -> tuple[int, int] | None:
    """``(H, W)`` a PNG or JPEG header declares, or None (another format, or no size found)."""
    if data.startswith(_PNG_SIGNATURE) and len(data) >= 24 and data[12:16] == b"IHDR":
        w, h = struct.unpack(">II", data[16:24])
        return h, w
    if data.startswith(b"\xff\xd8"):
        i = 2
        while i + 9 <= len(data):
            if data[i] != 0xFF:
                return None
            marker = data[i + 1]
            if marker == 0xFF:  # fill byte
                i += 1
                continue
            if marker in (0xD8, 0x01) or 0xD0 <= marker <= 0xD7:  # markers without a length
                i += 2
                continue
            length = struct.unpack(">H", data[i + 2 : i + 4])[0]
            if marker in _JPEG_SOF:
                h, w = struct.unpack(">HH", data[i + 5 : i + 9])
                return h, w
            i += 2 + length
    return None


def read_image(path: str | os.PathLike) -> np.ndarray | None:
    """The image as BGR uint8 ``(H, W, 3)``, or ``None`` when it is missing, truncated, not an image, not a regular
    file, or larger than `MAX_IMAGE_PIXELS` / ``MAX_IMAGE_SIDE`` / `MAX_IMAGE_BYTES`."""
    path = Path(path)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)  # a FIFO opens without waiting for a writer
    except OSError:
        return None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode) or info.st_size > MAX_IMAGE_BYTES:
            return None
        with os.fdopen(os.dup(fd), "rb") as f:
            data = f.read(MAX_IMAGE_BYTES + 1)
    finally:
        os.close(fd)
    suffix = path.suffix.lower()
    if suffix in (".jpg", ".jpeg") and not data.rstrip(b"\x00").endswith(_JPEG_END):
        return None
    if suffix == ".png" and _PNG_END not in data[-16:]:
        return None
    if not data or len(data) > MAX_IMAGE_BYTES:
        return None
    size = declared_size(data)
    if size is not None and (max(size) > MAX_IMAGE_SIDE or size[0] * size[1] > MAX_IMAGE_PIXELS):
        return None
    return cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)


def open_video(path: str | os.PathLike, error: type[Exception] = ValueError) -> cv2.VideoCapture:
    """An opened ``cv2.VideoCapture`` of a regular video file whose frames fit `MAX_IMAGE_PIXELS` and
    ``MAX_IMAGE_SIDE``.

    Raises:
        error: not a regular file (a FIFO would block the decoder until something writes to it, a device never
            end), not a video OpenCV can open, or frames declared larger than the limits (each would be allocated
            at that size).
    """
    try:
        mode = os.stat(path).st_mode
    except OSError as e:
        raise error(f"cannot open video {path}: {e.strerror}") from None
    if not stat.S_ISREG(mode):
        raise error(f"cannot open video {path}: a FIFO, device or directory, not a video file")
    capture = cv2.VideoCapture(str(path))
    if not capture.isOpened():
        raise error(f"cannot open video {path}")
    w, h = int(capture.get(cv2.CAP_PROP_FRAME_WIDTH)), int(capture.get(cv2.CAP_PROP_FRAME_HEIGHT))
    if max(w, h) > MAX_IMAGE_SIDE or w * h > MAX_IMAGE_PIXELS:
        capture.release()
        raise error(
            f"video {path} declares {w}x{h} frames, over the limit ({MAX_IMAGE_SIDE} px a side, "
            f"{MAX_IMAGE_PIXELS >> 20} Mpx)"
        )
    return capture
