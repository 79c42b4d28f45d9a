"""What identifies a frame: the one home of the digests stamlane keys a frame by, and of why there are two.

A frame has an identity of its pixels and one of its file, each for the cache that cannot use the other:

- `frame_digest` (SHA-256 of an image's shape, dtype and pixels): what the ORB estimator reads, whatever the file's
  encoding or place. It names the entries of the content-keyed pair cache (`stamlane.align.cache.PairCache`), which
  outlives the process and is shared by every data set: an entry there must be right for whoever reads it later, so
  it is keyed by what was estimated, never by a file that may be rewritten between its reading and its decoding.
- `file_identity` (BLAKE2b-128 of the file's bytes, read again at every use: about 0.1 ms a frame): known BEFORE
  the frame is decoded. It names the entries of the process's in-memory frame store
  (`stamlane.data.frame_store.FrameStore`: the decoded, aligned and resized frames and each clip's alignment),
  whose whole point is that a hit decodes nothing; a file written again with other bytes is another frame there.

Both are pure functions of what they read: the same pixels (the same bytes) always give the same digest, so a hit
holds what computing afresh would give, bit for bit.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from stamlane.safety.images import read_image_file

__all__ = ["file_identity", "frame_digest"]


def frame_digest(image: np.ndarray) -> str:
    """SHA-256 of a frame's shape, dtype and pixels (what the estimator reads), hex."""
    image = np.ascontiguousarray(image)
    digest = hashlib.sha256(f"{image.shape}{image.dtype.str}".encode())
    digest.update(image.data.cast("B"))
    return digest.hexdigest()


def file_identity(path: Path) -> str | None:
    """The digest of a file's bytes (BLAKE2b, 128 bits), hex, or None when it is not a regular file of at most
    `stamlane.safety.images.MAX_IMAGE_BYTES` that can be read (the image reader then says why)."""
    try:
        data = read_image_file(path)
    except OSError:
        return None
    if data is None:
        return None
    return hashlib.blake2b(data, digest_size=16).hexdigest()
