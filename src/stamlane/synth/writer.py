"""Store a rendered clip and label files: frames as JPEG, labels and homographies as JSON, each file atomically.

Every file goes through ``stamlane.safety.guard.atomic_path`` (a temporary name beside it, then a rename): a
generation killed half-way leaves whole files or none, never a truncated label or index file that a later run would
read as complete.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import cv2

from stamlane.safety.guard import atomic_path, write_atomic
from stamlane.synth.clip import SynthClip
from stamlane.synth.layout import key_frames

__all__ = ["write_clip", "write_json_lines"]


def write_clip(
    clip: SynthClip, root: Path, clip_id: str, jpeg_quality: int = 92, key_step: int = 0, folder: str | None = None
) -> list[dict[str, Any]]:
    """Write a clip's frames, per-frame labels and homographies under ``root``.

    Args:
        clip: the rendered clip.
        root: the set's folder.
        clip_id: the clip's id (``train-0007``): ``frame_labels/<id>.json`` and ``homographies/<id>.json``.
        jpeg_quality: of the frames.
        key_step: which frames are labelled key frames (`key_frames`).
        folder: where the frames go, relative to ``root`` (default ``clips/<clip_id>``; TuSimple's layout:
            ``clips/<date>/<clip_id>``, `stamlane.synth.tusimple_layout.clip_folder`).

    Returns:
        the TuSimple label records (``raw_file``, ``lanes``, ``h_samples``) of the clip's key frames
        (`key_frames` with ``key_step``), oldest first.
    """
    rel = folder if folder is not None else f"clips/{clip_id}"
    folder_path = root / rel
    names = [f"{i + 1}.jpg" for i in range(len(clip.frames))]
    for name, frame in zip(names, clip.frames):
        ok, buf = cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, jpeg_quality])
        if not ok:
            raise OSError(f"could not encode {folder_path / name}")
        with atomic_path(folder_path / name) as tmp:
            tmp.write_bytes(buf.tobytes())
    raw = [f"{rel}/{name}" for name in names]
    per_frame = [
        {"raw_file": r, "lanes": lanes, "h_samples": clip.h_samples, "occluded": occ}
        for r, lanes, occ in zip(raw, clip.labels, clip.occluded)
    ]
    write_atomic(root / "frame_labels" / f"{clip_id}.json", json.dumps(per_frame))
    last = len(clip.frames) - 1
    geometry = {
        "frames": names,
        "image_from_ground": [h.tolist() for h in clip.image_from_ground],
        "last_from_frame": [clip.key_from_hist(last, j).tolist() for j in range(len(names))],
        "next_from_frame": [clip.key_from_hist(j + 1, j).tolist() for j in range(len(names) - 1)],
    }
    write_atomic(root / "homographies" / f"{clip_id}.json", json.dumps(geometry))
    return [
        {"raw_file": raw[k], "lanes": clip.labels[k], "h_samples": clip.h_samples}
        for k in key_frames(len(names), key_step)
    ]


def write_json_lines(path: Path, records: list[dict[str, Any]]) -> None:
    """Write ``records`` to ``path`` as JSON lines (one object a line, each line ended: the TuSimple label files'
    format), atomically; its folder is created when missing."""
    write_atomic(path, "".join(json.dumps(r) + "\n" for r in records))
