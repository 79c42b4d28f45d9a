"""Reading frames: a truncated file is unreadable, not a grey picture; a hostile one costs bounded memory.

``cv2.imread`` decodes a JPEG cut short into a full-size image whose missing part is grey (it only prints a
warning), so a broken download would train and score silently. `read_image` checks that a JPEG ends with its
end-of-image marker and a PNG with its ``IEND`` chunk before decoding.

A decompression bomb (a few KiB of PNG declaring 100,000 x 100,000 pixels) would make the decoder allocate the
declared size: the PNG, JPEG or BMP header is read first (a JPEG's markers as libjpeg reads them: stuffed and fill
bytes skipped, every segment by its length) and an image over `MAX_IMAGE_PIXELS` or with a side over
``stamlane_eval.io.MAX_IMAGE_SIDE`` is refused before decoding; so is an image whose size cannot be read (another
format, a header without a frame size): OpenCV decodes by content, whatever the name, up to its own limit of a
gigapixel.
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

__all__ = ["MAX_IMAGE_BYTES", "MAX_IMAGE_PIXELS", "declared_size", "open_video", "read_image", "read_image_file"]

MAX_IMAGE_PIXELS = 1 << 26
"""Most pixels in one frame (67 Mpx, twice 8K UHD): 192 MiB decoded as BGR."""
MAX_IMAGE_BYTES = 256 << 20
"""Largest image file read (256 MiB)."""

_JPEG_END = b"\xff\xd9"
_PNG_END = b"IEND"
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_JPEG_SOF = {0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF}
"""Start-of-frame markers SOF0-SOF15 (baseline, extended, progressive, lossless, arithmetic), which hold the size;
not DHT (C4), JPG (C8) nor DAC (CC), which share their range (ITU T.81, table B.1)."""
_JPEG_NO_LENGTH = {0x01, *range(0xD0, 0xD8)}
"""Markers without a length field: TEM and the restart markers RST0-RST7."""
_EXIF_ORIENTATION = 0x0112
"""The EXIF tag of the orientation; values 5-8 turn the picture a quarter: OpenCV's decoder swaps width and height."""


def _jpeg_size(data: bytes) -> tuple[int, int] | None:
    """``(H, W)`` of a JPEG as libjpeg reads its markers (``jdmarker.c``, ``next_marker``): bytes between segments
    that are not a marker are skipped, fill bytes (``FF FF``) and stuffed zeros (``FF 00``) too, each segment by its
    length field, up to the first start-of-frame; None when the scan or the end comes first (libjpeg refuses such
    a file), a segment is cut short or SOI comes twice. EXIF orientations 5-8 swap the sides, as the decoder does."""
    i, n, turned = 2, len(data), False
    while True:
        while i < n and data[i] != 0xFF:  # not a marker: libjpeg warns ("extraneous bytes") and skips
            i += 1
        while i < n and data[i] == 0xFF:  # fill bytes
            i += 1
        if i >= n:
            return None
        marker = data[i]
        i += 1
        if marker == 0x00:  # a stuffed zero outside a scan: discarded, the search goes on
            continue
        if marker in _JPEG_NO_LENGTH:
            continue
        if marker in (0xD8, 0xD9, 0xDA):  # SOI again, the end, or the scan before any frame header
            return None
        if i + 2 > n:
            return None
        length = struct.unpack(">H", data[i : i + 2])[0]
        if length < 2 or i + length > n:
            return None
        if marker in _JPEG_SOF:
            if length < 7:
                return None
            h, w = struct.unpack(">HH", data[i + 3 : i + 7])
            return (w, h) if turned else (h, w)
        if marker == 0xE1 and data[i + 2 : i + 8] == b"Exif\x00\x00":
            turned = _exif_orientation(data[i + 8 : i + length]) in (5, 6, 7, 8)
        i += length


def _exif_orientation(tiff: bytes) -> int | None:
    """The orientation tag of IFD0 of an EXIF block (TIFF layout), or None."""
    if len(tiff) < 8 or tiff[:2] not in (b"II", b"MM"):
        return None
    order = "<" if tiff[:2] == b"II" else ">"
    first = struct.unpack(order + "I", tiff[4:8])[0]
    if first + 2 > len(tiff):
        return None
    count = struct.unpack(order + "H", tiff[first : first + 2])[0]
    for k in range(count):
        at = first + 2 + 12 * k
        if at + 12 > len(tiff):
            return None
        tag, kind = struct.unpack(order + "HH", tiff[at : at + 4])
        if tag == _EXIF_ORIENTATION and kind == 3:  # SHORT
            orientation: int = struct.unpack(order + "H", tiff[at + 8 : at + 10])[0]
            return orientation
    return None


def _bmp_size(data: bytes) -> tuple[int, int] | None:
    if len(data) < 26:
        return None
    header = struct.unpack("<I", data[14:18])[0]
    if header == 12:  # BITMAPCOREHEADER: 16-bit sides
        w, h = struct.unpack("<HH", data[18:22])
        return h, w
    w, h = struct.unpack("<ii", data[18:26])
    return abs(h), abs(w)  # a negative height: rows top-down


def declared_size(data: bytes) -> tuple[int, int] | None:
    """``(H, W)`` a PNG, JPEG or BMP header declares (as OpenCV decodes it: a JPEG's EXIF orientation applied), or
    None: another format, or a header whose size cannot be read."""
    if data.startswith(_PNG_SIGNATURE):
        if len(data) >= 24 and data[12:16] == b"IHDR":
            w, h = struct.unpack(">II", data[16:24])
            return h, w
        return None
    if data.startswith(b"\xff\xd8"):
        return _jpeg_size(data)
    if data.startswith(b"BM"):
        return _bmp_size(data)
    return None


def read_image_file(path: str | os.PathLike[str]) -> bytes | None:
    """The bytes of an image file: None when it cannot be opened, is not a regular file or holds more than
    `MAX_IMAGE_BYTES`. Opened without blocking, so a FIFO opens without waiting for a writer; an error of the read
    itself is raised (`OSError`)."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except OSError:
        return None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode) or info.st_size > MAX_IMAGE_BYTES:
            return None
        with os.fdopen(os.dup(fd), "rb") as f:
            return f.read(MAX_IMAGE_BYTES + 1)
    finally:
        os.close(fd)


def read_image(path: str | os.PathLike[str]) -> np.ndarray | None:
    """The image as BGR uint8 ``(H, W, 3)``, or ``None`` when it is missing, truncated, not an image, not a regular
    file, or larger than `MAX_IMAGE_PIXELS` / ``MAX_IMAGE_SIDE`` / `MAX_IMAGE_BYTES`."""
    path = Path(path)
    data = read_image_file(path)
    if data is None:
        return None
    suffix = path.suffix.lower()
    if suffix in (".jpg", ".jpeg") and not data.rstrip(b"\x00").endswith(_JPEG_END):
        return None
    if suffix == ".png" and _PNG_END not in data[-16:]:
        return None
    if not data or len(data) > MAX_IMAGE_BYTES:
        return None
    size = declared_size(data)  # nothing is decoded whose size was not read and checked first
    if size is None or min(size) < 1 or max(size) > MAX_IMAGE_SIDE or size[0] * size[1] > MAX_IMAGE_PIXELS:
        return None
    return cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)


def open_video(path: str | os.PathLike[str], error: type[Exception] = ValueError) -> cv2.VideoCapture:
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
