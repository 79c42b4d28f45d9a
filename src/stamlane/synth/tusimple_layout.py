"""TuSimple's own layout of a synthetic set (``stamlane synth --layout tusimple``): what TuSimple's data looks like,
so that a reader, a config or a tool made for TuSimple reads the synthetic set unchanged.

TuSimple's lane benchmark (``train_set/`` and ``test_set/`` merged, as ``configs/tusimple_stam4.yaml`` reads it)::

    <root>/clips/<date>/<clip>/1.jpg .. 20.jpg   20 frames of one second, the key frame 20.jpg
    <root>/label_data_0313.json                  train labels (clips/0313-1/, clips/0313-2/), 20.jpg alone
    <root>/label_data_0531.json                  train labels (clips/0531/): the paper configs' val split
    <root>/label_data_0601.json                  train labels (clips/0601/)
    <root>/test_label.json                       test labels (clips/0530/, 0531/, 0601/)

every record with ``h_samples`` 160, 170 .. 710 of the 1280x720 frames (-2 where a lane has no point). The
generator's own layout (`stamlane.synth.layout`) differs in three ways, each of which a TuSimple tool notices:
clips one folder deep (``clips/<id>/``), label rows from 80 m ahead (330 .. 710 at 720 rows), and several
labelled frames per clip (so ``stamlane align`` needs ``--key-frames all``). In the TuSimple layout a synthetic
set is written as TuSimple is:

- ``train`` clips go to ``clips/0313-1/<id>/`` (even clips) and ``clips/0601/<id>/`` (odd clips), labelled in
  ``label_data_0313.json`` and ``label_data_0601.json``; ``val`` clips to ``clips/0531/<id>/``
  (``label_data_0531.json``: the paper configs' val split); ``test`` clips to ``clips/0530/<id>/``
  (``test_label.json``). ``<id>`` is the clip's id (``train-0007``), so ``frame_labels/<id>.json``,
  ``homographies/<id>.json`` and ``dataset.json``'s ``clip_factors`` name it as in the generator's layout;
- the challenging and reveal splits, which TuSimple does not have, go to ``clips/<split>/<id>/`` with the label
  files of the generator's layout (``challenging.json``, ``challenging-<factor>.json``, ...);
- the last frame of each clip alone is labelled (key step 0);
- ``h_samples`` are TuSimple's 56 rows scaled to the frame height (`tusimple_rows`): 160 .. 710 at 720 rows, the
  rows a TuSimple frame resized to that height has (80, 85 .. 355 at 360 rows).

The frames are the generator layout's, pixel for pixel (clip ``i`` of a split depends on ``(seed, split, i)``
alone); only the label rows, the key frames and the paths differ. The standard library alone, as
`stamlane.synth.layout`.
"""

from __future__ import annotations

__all__ = [
    "LAYOUTS",
    "TUSIMPLE_HEIGHT",
    "TUSIMPLE_LABEL_FILES",
    "TUSIMPLE_ROWS",
    "clip_folder",
    "label_file",
    "split_label_files",
    "tusimple_rows",
]

LAYOUTS = ("stamlane", "tusimple")
"""The layouts a set can be written in: the generator's own (`stamlane.synth.layout`) and TuSimple's."""
TUSIMPLE_HEIGHT = 720
"""Rows of a TuSimple frame (1280x720)."""
TUSIMPLE_ROWS = tuple(range(160, 720, 10))
"""TuSimple's ``h_samples`` at 720 rows: 160, 170 .. 710 (56 rows; every record of ``label_data_0313.json``,
``label_data_0601.json`` and most of ``test_label.json``; the 0531 clips start at 240)."""
_FOLDERS = {"train": ("0313-1", "0601"), "val": ("0531",), "test": ("0530",)}
"""TuSimple's date folders of each split; a train clip ``i`` goes to the ``i % 2``-th."""
TUSIMPLE_LABEL_FILES = {
    "0313-1": "label_data_0313.json",
    "0601": "label_data_0601.json",
    "0531": "label_data_0531.json",
    "0530": "test_label.json",
}
"""The label file of each date folder, as TuSimple names them."""


def tusimple_rows(height: int) -> list[int]:
    """TuSimple's `TUSIMPLE_ROWS` scaled to a frame of ``height`` rows (rounded; a row once where two round to it).

    Raises:
        ValueError: a height below 1.
    """
    if height < 1:
        raise ValueError(f"height must be >= 1, got {height}")
    return list(dict.fromkeys(round(row * height / TUSIMPLE_HEIGHT) for row in TUSIMPLE_ROWS))


def _check(layout: str) -> None:
    if layout not in LAYOUTS:
        raise ValueError(f"layout must be one of {LAYOUTS}, got {layout!r}")


def clip_folder(layout: str, split: str, index: int) -> str:
    """The folder (relative to the set's root) of clip ``index`` of ``split``: ``clips/<id>`` in the generator's
    layout, ``clips/<date>/<id>`` in TuSimple's (``<date>`` the split's name for the splits TuSimple has not)."""
    _check(layout)
    clip_id = f"{split}-{index:04d}"
    if layout == "stamlane":
        return f"clips/{clip_id}"
    dates = _FOLDERS.get(split, (split,))
    return f"clips/{dates[index % len(dates)]}/{clip_id}"


def label_file(layout: str, split: str, index: int) -> str:
    """The label file that lists clip ``index`` of ``split``: ``<split>.json``, or TuSimple's name of its date."""
    _check(layout)
    if layout == "stamlane" or split not in _FOLDERS:
        return f"{split}.json"
    dates = _FOLDERS[split]
    return TUSIMPLE_LABEL_FILES[dates[index % len(dates)]]


def split_label_files(layout: str, split: str) -> list[str]:
    """Every label file of ``split``'s clips in ``layout`` (written even when it lists no clip)."""
    _check(layout)
    if layout == "stamlane" or split not in _FOLDERS:
        return [f"{split}.json"]
    return [TUSIMPLE_LABEL_FILES[date] for date in _FOLDERS[split]]
