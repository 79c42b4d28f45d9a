"""Aligned frames on disk (``stamlane align --write-frames OUT``): each key frame's history frames warped onto it.

Under ``OUT/<clip folder relative to the data root>/``: ``<key stem>_back<n><suffix>`` is the frame ``n`` frames
before the key frame warped onto it with the cached ``key_from_hist`` (``<key stem>_back0`` is a byte copy of the
key frame), and ``aligned.json`` (``MANIFEST_NAME``) records each file's source, homography and whether its
alignment succeeded (a failed one is written UNWARPED, ``ok: false``). numpy/OpenCV only.
"""

from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from stamlane.align.cache import CacheDict, alignment_from_json, read_cache, write_cache
from stamlane.align.warp import warp_to_key
from stamlane.safety.guard import atomic_path, make_folder

__all__ = [
    "MANIFEST_NAME",
    "aligned_frame_name",
    "mirror",
    "missing_outputs",
    "planned_outputs",
    "write_aligned_frames",
]

MANIFEST_NAME = "aligned.json"
"""Per clip folder of ``--write-frames OUT``: what each written file is and whether its alignment succeeded."""

JPEG_QUALITY = 95  # written .jpg frames; .png frames stay lossless


def mirror(out_root: Path, root: Path, clip_dir: Path) -> Path:
    """``out_root/<clip_dir relative to root>``."""
    return out_root / clip_dir.resolve().relative_to(root.resolve())


def aligned_frame_name(key: Path, frame: Path, back: int) -> str:
    """File name of ``frame`` aligned to ``key``: ``<key stem>_back<back><frame suffix>``.

    ``back`` counts frames of the folder (in frame-number order) between the frame and the key frame:
    TuSimple ``20.jpg`` with ``--stride 2`` gives ``20_back2.jpg`` (from ``18.jpg``), ``20_back4.jpg``, ...;
    ``back`` 0 is the key frame itself. The suffix is the source frame's (``.png`` stays lossless).
    """
    return f"{key.stem}_back{back}{frame.suffix}"


def planned_outputs(frames: list[Path], pairs: dict[int, list[int]]) -> list[tuple[int, int, str]]:
    """``(key index, frame index, output name)`` of every file ``--write-frames`` writes for a clip."""
    return [(k, i, aligned_frame_name(frames[k], frames[i], k - i)) for k, hist in pairs.items() for i in [*hist, k]]


def missing_outputs(out_dir: Path, frames: list[Path], pairs: dict[int, list[int]]) -> bool:
    """Whether some file ``write_aligned_frames`` would write is absent or not in the manifest."""
    manifest = read_cache(out_dir / MANIFEST_NAME)
    return any(
        name not in manifest.get(frames[k].name, {}) or not (out_dir / name).is_file()
        for k, _, name in planned_outputs(frames, pairs)
    )


def _write_image(path: Path, image: np.ndarray) -> None:
    """``cv2.imwrite`` through `stamlane.safety.guard.atomic_path`, so an interrupted run never leaves a half-written
    frame.

    Raises:
        OSError: OpenCV could not write it.
    """
    params = [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY] if path.suffix.lower() in (".jpg", ".jpeg") else []
    with atomic_path(path) as tmp:
        if not cv2.imwrite(str(tmp), image, params):
            raise OSError(f"could not write {path}")


def write_aligned_frames(
    out_dir: Path,
    frames: list[Path],
    pairs: dict[int, list[int]],
    cache: CacheDict,
    read_image: Callable[[int], np.ndarray | None],
) -> tuple[int, int]:
    """Write one clip folder's history frames warped onto their key frames, with a manifest.

    For each key frame ``k`` and history frame ``i`` of ``pairs``, ``out_dir/<aligned_frame_name>`` holds
    the history frame warped by the cached ``key_from_hist`` (``warp_to_key``: the whole frame, key-frame
    pixels, 0 where it has no source; the homography holds for the ground only), and ``<key stem>_back0``
    a byte copy of the key frame. A history frame whose alignment FAILED is written unwarped. The
    manifest ``out_dir/aligned.json`` says so::

        {"20.jpg": {"20_back1.jpg": {"source": "19.jpg", "back": 1, "ok": true, "reason": "",
                                     "key_from_hist": [[...], [...], [...]]}, ...}}

    ``ok`` False: written unwarped (``key_from_hist`` the identity), ``reason`` says why. Files already
    listed in the manifest and present are not rewritten.

    Args:
        out_dir: the clip folder's output folder.
        frames: the clip folder's frames, frame-number order.
        pairs: ``{key index: [history indices]}`` (``requested_pairs``).
        cache: the clip folder's cache, covering ``pairs`` (``stamlane.align.cache`` layout).
        read_image: ``read_image(i)`` returns frame ``i`` as uint8 ``(H, W, 3)`` BGR, or None if unreadable.

    Returns:
        ``(files written, history frames written unwarped because their alignment failed)``.
    """
    manifest_path = out_dir / MANIFEST_NAME
    manifest = read_cache(manifest_path)
    written = unaligned = 0
    changed = False
    make_folder(out_dir)
    for k, i, name in planned_outputs(frames, pairs):
        key, target = frames[k], out_dir / name
        entry = manifest.setdefault(key.name, {})
        if name in entry and target.is_file():
            continue
        changed = True
        if i == k:
            if not target.is_file():
                with atomic_path(target) as tmp:
                    shutil.copyfile(key, tmp)
                written += 1
            entry[name] = {"source": key.name, "back": 0, "ok": True, "reason": "", "key_from_hist": np.eye(3).tolist()}
            continue
        alignment = alignment_from_json(cache[key.name][frames[i].name])
        record: dict[str, Any] = {
            "source": frames[i].name,
            "back": k - i,
            "ok": alignment.ok,
            "reason": alignment.reason,
        }
        record["key_from_hist"] = np.asarray(alignment.key_from_hist, float).tolist()
        if not target.is_file():
            image = read_image(i)
            if image is None:
                record["reason"] = record["reason"] or f"could not read {frames[i].name}"
                record["ok"] = False
                entry[name] = record  # nothing to write; retried next run
                continue
            aligned = warp_to_key(image, alignment.key_from_hist) if alignment.ok else image
            _write_image(target, aligned)
            written += 1
            unaligned += not alignment.ok
        entry[name] = record
    if changed:
        write_cache(manifest_path, manifest)
    return written, unaligned
