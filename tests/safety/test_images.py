"""stamlane.safety.images: a truncated frame is unreadable everywhere (datasets, align), never a grey picture."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

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
    from stamlane.data.labels import DataError
    from stamlane.data.layouts import TuSimpleClips
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


def _jpeg(shape: tuple[int, int] = (40, 60), progressive: bool = False) -> bytes:
    ok, data = cv2.imencode(
        ".jpg", _picture()[: shape[0], : shape[1]], [cv2.IMWRITE_JPEG_PROGRESSIVE, int(progressive)]
    )
    assert ok
    return data.tobytes()


def _exif(orientation: int) -> bytes:
    """An APP1 segment holding an EXIF block whose IFD0 has the orientation tag only (little-endian TIFF)."""
    import struct

    tiff = b"II*\x00" + struct.pack("<I", 8) + struct.pack("<H", 1)
    tiff += struct.pack("<HHIHH", 0x0112, 3, 1, orientation, 0) + struct.pack("<I", 0)
    body = b"Exif\x00\x00" + tiff
    return b"\xff\xe1" + struct.pack(">H", len(body) + 2) + body


def _variants(data: bytes) -> dict[str, bytes]:
    """The same JPEG with what libjpeg skips before the frame header: fill bytes, a stuffed zero, stray bytes; a
    comment segment holding ``FF C0``; an EXIF block that turns it a quarter."""
    app0_end = 4 + int.from_bytes(data[4:6], "big")
    head, tail = data[:app0_end], data[app0_end:]
    comment = b"\xff\xfe\x00\x08\xff\xc0\x00\x11\x08\x00"  # a COM segment whose text looks like a SOF
    return {
        "plain": data,
        "fill-bytes": head + b"\xff\xff\xff" + tail,
        "stuffed-zero": head + b"\xff\x00" + tail,
        "stray-bytes": head + b"\x12\x34\xff\x00\x56" + tail,
        "comment-like-sof": head + comment + tail,
        "exif-turned": data[:2] + _exif(6) + data[2:],
        "exif-upright": data[:2] + _exif(1) + data[2:],
    }


@pytest.mark.parametrize("progressive", [False, True])
def test_the_jpeg_header_is_read_as_the_decoder_reads_it(progressive: bool) -> None:
    """Oracle: OpenCV's own decode of small files: the size read from the header is the decoded size, whatever
    libjpeg skips before the frame header, for baseline and progressive files, with EXIF orientation applied."""
    from stamlane.safety.images import declared_size

    for name, data in _variants(_jpeg((40, 60), progressive)).items():
        decoded = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
        assert decoded is not None, name
        assert declared_size(data) == decoded.shape[:2], name


def test_a_huge_jpeg_behind_a_stuffed_marker_is_never_decoded(tmp_path: Path) -> None:
    """A 20000 x 20000 JPEG (400 Mpx, 1.2 GB decoded) whose frame header follows an ``FF 00``: the size is read past
    it and the file refused before decoding (only the header is crafted: the decoder would allocate from it)."""
    import struct

    from stamlane.safety.images import MAX_IMAGE_PIXELS, declared_size

    data = _variants(_jpeg())["stuffed-zero"]
    sof = data.index(b"\xff\xc0")
    huge = data[: sof + 5] + struct.pack(">HH", 20_000, 20_000) + data[sof + 9 :]
    assert declared_size(huge) == (20_000, 20_000) and 20_000**2 > MAX_IMAGE_PIXELS
    (tmp_path / "huge.jpg").write_bytes(huge)
    assert read_image(tmp_path / "huge.jpg") is None


@pytest.mark.parametrize(
    "data",
    [
        b"\xff\xd8\xff\xda\x00\x02" + b"\x00" * 50 + b"\xff\xd9",  # the scan before any frame header
        b"\xff\xd8\xff\xe0\x00\x01" + b"\x00" * 50 + b"\xff\xd9",  # a segment length below 2
        b"\xff\xd8\xff\xd8" + b"\x00" * 50 + b"\xff\xd9",  # SOI twice
        b"\xff\xd8\xff\xe0\xff\xff" + b"\x00" * 50 + b"\xff\xd9",  # a segment past the end
        b"GIF89a" + b"\x00" * 50,  # a format whose size stamlane does not read
    ],
    ids=["scan-first", "short-length", "two-soi", "past-the-end", "gif"],
)
def test_an_image_whose_size_cannot_be_read_is_refused_not_decoded(tmp_path: Path, data: bytes) -> None:
    from stamlane.safety.images import declared_size

    assert declared_size(data) is None
    (tmp_path / "x.jpg").write_bytes(data)
    assert read_image(tmp_path / "x.jpg") is None


def test_bmp_sizes_are_read(tmp_path: Path) -> None:
    from stamlane.safety.images import declared_size

    ok, data = cv2.imencode(".bmp", _picture())
    assert ok and declared_size(data.tobytes()) == (48, 64)
    (tmp_path / "f.bmp").write_bytes(data.tobytes())
    assert read_image(tmp_path / "f.bmp").shape == (48, 64, 3)


def _boundaries(data: bytes) -> list[int]:
    """Where each segment before the scan starts (after SOI), in a file as OpenCV writes it."""
    at, found = 2, []
    while data[at + 1] != 0xDA:
        found.append(at)
        at += 2 + int.from_bytes(data[at + 2 : at + 4], "big")
    return [*found, at]


JUNK = [b"\xff", b"\xff\xff\xff", b"\xff\x00", b"\x00", b"\x12\x34", b"\xff\x00\xff\x00", b"\xfe"]


@settings(max_examples=60, deadline=None, derandomize=True, database=None)
@given(
    progressive=st.booleans(),
    turned=st.sampled_from([None, 1, 6, 8, 3]),
    junk=st.lists(st.tuples(st.integers(0, 20), st.sampled_from(JUNK)), max_size=4),
    huge=st.booleans(),
)
def test_fuzz_jpeg_headers_as_the_decoder_reads_them(
    tmp_path_factory: pytest.TempPathFactory, progressive: bool, turned: int | None, junk: list, huge: bool
) -> None:
    """Property: whatever libjpeg skips between the segments before the frame header (fill bytes, stuffed zeros,
    stray bytes), with EXIF orientation or progressive coding, the size read from the header is the size OpenCV
    decodes, or the file is not decoded by either; a 20000 x 20000 frame header is never decoded."""
    import struct

    from stamlane.safety.images import declared_size

    data = _jpeg((40, 60), progressive)
    if turned is not None:
        data = data[:2] + _exif(turned) + data[2:]
    cuts = _boundaries(data)
    for pick, bytes_ in sorted(junk, reverse=True):  # from the end, so the earlier positions hold
        at = cuts[pick % len(cuts)]
        data = data[:at] + bytes_ + data[at:]
        cuts = _boundaries_after(data)
    if huge:
        sof = max(data.rfind(b"\xff\xc0"), data.rfind(b"\xff\xc2"))
        data = data[: sof + 5] + struct.pack(">HH", 20_000, 20_000) + data[sof + 9 :]
    size = declared_size(data)
    path = tmp_path_factory.mktemp("jpeg") / "f.jpg"
    path.write_bytes(data)
    if huge:
        assert size is None or max(size) == 20_000
        assert read_image(path) is None
        return
    decoded = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    if decoded is None:
        assert read_image(path) is None
    else:
        assert size == decoded.shape[:2], (size, decoded.shape)
        assert read_image(path).shape == decoded.shape


def _boundaries_after(data: bytes) -> list[int]:
    """`_boundaries` of a file that may hold junk between segments: each segment's marker, found as libjpeg finds
    it (junk skipped)."""
    at, found = 2, []
    while at < len(data):
        while data[at] != 0xFF:
            at += 1
        while data[at] == 0xFF:
            at += 1
        marker = data[at]
        at += 1
        if marker == 0x00:
            continue
        found.append(at - 2)
        if marker == 0xDA:
            return found
        at += int.from_bytes(data[at : at + 2], "big")
    return found
