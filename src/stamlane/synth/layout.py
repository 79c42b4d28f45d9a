"""What a synthetic set looks like on disk: its splits, files, format version and labelled key frames.

The facts ``stamlane.data`` and ``stamlane.experiments`` read a set by, in a module of the standard library alone:
importing it loads neither numpy nor OpenCV nor the renderer (``tests/synth/test_layout.py``). The settings and
the challenging factors are `stamlane.synth.config`'s; ``generate_dataset`` (`stamlane.synth.dataset`) writes
this layout (``<id>`` like ``train-0007``)::

    <root>/clips/<id>/1.jpg .. <T>.jpg          frames, oldest first; the key frame is <T>.jpg
    <root>/{train,val,test,challenging}.json    TuSimple label json-lines of each clip's KEY frames: the last
                                                frame and every ``key_step``-th frame before it, down to frame
                                                ``FIRST_KEY + 1`` (so every key frame has >= 7 history frames)
    <root>/{reveal,reveal-traffic}.json         the key frame (the last of 12) of each clip of the two splits
                                                where the history reveals lanes (``config.REVEAL``,
                                                ``config.REVEAL_TRAFFIC``)
    <root>/<split>-<kind>.json                  the key frames of each factor or kind of the challenging,
                                                reveal and reveal-traffic splits
    <root>/{train,val}-clean.json               the clean clips' key frames alone (sets with factor clips)
    <root>/challenging-frames.json              every frame of a few challenging clips (`TEMPORAL_LABELS`)
    <root>/frame_labels/<id>.json               TuSimple-style labels of EVERY frame (+ "occluded" flags)
    <root>/homographies/<id>.json               true geometry: image_from_ground per frame, and
                                                last_from_frame / next_from_frame (= key_from_hist)
    <root>/visibility/<split>.json              per key frame of the split's labels, per labelled point: where
                                                its paint is visible (key frame / history only / nowhere;
                                                ``stamlane.synth.visibility``)
    <root>/dataset.json                         generator settings and statistics (written last: a set without
                                                it is incomplete)

Every file is written under a temporary name and renamed (``stamlane.safety.guard.atomic_path``): a generation
that is killed leaves whole files or none.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

__all__ = [
    "DEFAULT_SYNTHETIC_ROOT",
    "DEMO_SPLITS",
    "EVAL_KEY_STEP",
    "FIRST_KEY",
    "FORMAT_VERSION",
    "KIND_SPLITS",
    "REVEAL_FRAMES",
    "SPLITS",
    "TEMPORAL_CLIPS_PER_FACTOR",
    "TEMPORAL_LABELS",
    "TRAIN_KEY_STEP",
    "VISIBILITY_DIR",
    "SplitCounts",
    "key_frames",
]

SPLITS = ("train", "val", "test", "challenging", "reveal", "reveal-traffic")
"""Every split of a set, in the order of their seeds' codes (clip ``i`` of split ``SPLITS[c]`` draws from
``(seed, c, i)``: a split added at the end leaves every clip before it as it was)."""
KIND_SPLITS = ("challenging", "reveal", "reveal-traffic")
"""Splits whose every clip has a named factor or kind, with a label file per kind (``<split>-<kind>.json``)."""
FORMAT_VERSION = 7
"""7: ``SynthConfig.world``: the ``dashcam`` world (`stamlane.synth.dashcam`: a camera spread over dashcam ranges,
marking standards with raised pavement markers, concrete and asphalt with joints and seams, barriers and guard
rails, skies, sensor effects), what the real-road check (benchmarks/real_roads.py) asked for; the default
``classic`` world and every clip of format 6 are as they were, byte for byte; 6: the ``reveal`` and ``reveal-traffic`` splits (``config.REVEAL``, ``config.REVEAL_TRAFFIC``: 12-frame clips
where the history shows what the key frame hides) with their visibility over every history frame, and
``train_motion`` clips (the reveal splits' ego motion, no occluder) in the train split after its factor clips; every
clip of format 5 is as it was, byte for byte; 5: factor clips added to the train and val splits (``train_factors``,
``val_factors``; the clean clips and the test and challenging splits are format 4's, byte for byte) and the paint
visibility of every labelled key-frame point of the val, test and challenging splits (``visibility/<split>.json``);
4: the challenging split is made of labelled factors (``config.FACTORS``, one per clip; train, val and test are
format 3's, byte for byte); 3: several labelled key frames per clip (``key_step``), light traffic in the clean
splits; 2: 20 fps, asphalt grain near the camera, along-road prefiltering, vehicles 4-35 m ahead; 1: 10 fps,
3-30 m."""
DEFAULT_SYNTHETIC_ROOT = f"data/synthetic-v{FORMAT_VERSION}"
"""Where ``ClipDataModule(root=None)`` and ``stamlane demo`` read the synthetic set (relative to the working
directory; generated there when missing). Named by the format version, so a newer generator never reuses (or
overwrites) an older set."""


@dataclass(frozen=True)
class SplitCounts:
    """Clips per split of a synthetic set: the one place that names the splits' counts, read by the generator
    (`stamlane.synth.dataset.generate_dataset`), ``data.synth``'s options and ``stamlane synth`` (``--clips N``'s rule:
    `stamlane.synth.config.counts_of_total`).

    Attributes:
        train, val, test: clean clips of each split.
        challenging: clips of the challenging split, one challenging factor each.
        reveal, reveal_traffic: clips of the ``reveal`` and ``reveal-traffic`` splits.
        train_factors, val_factors: clips with a challenging factor added to the train and val splits.
        train_motion: clips with the reveal splits' ego motion added to the train split.

    The order of the fields is the order ``dataset.json`` records them in (``splits``).
    """

    train: int = 0
    val: int = 0
    test: int = 0
    challenging: int = 0
    reveal: int = 0
    reveal_traffic: int = 0
    train_factors: int = 0
    val_factors: int = 0
    train_motion: int = 0

    def __post_init__(self) -> None:
        for name, n in self.as_dict().items():
            if not isinstance(n, int) or isinstance(n, bool) or n < 0:
                raise ValueError(f"clip count of split {name!r} must be an int >= 0, got {n!r}")

    def as_dict(self) -> dict[str, int]:
        """The counts by field name, as ``dataset.json`` records them."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def total(self) -> int:
        """Every clip of the set."""
        return sum(self.as_dict().values())


DEMO_SPLITS = SplitCounts(
    train=120,
    val=20,
    test=100,
    challenging=128,
    reveal=90,
    reveal_traffic=60,
    train_factors=120,
    val_factors=32,
    train_motion=96,
)
"""Clips per split of the default set (``stamlane demo``, ``root: null``, ``stamlane synth --demo``): 120 clean and
120 factor clips (15 per factor) and 96 ``train_motion`` clips in train (what makes the fusion read its history,
docs/training.md); 20 clean and 32 factor val clips; 100 test and 128 challenging clips (16 per factor); 90 reveal
(30 per kind) and 60 reveal-traffic clips (30 per kind)."""
TRAIN_KEY_STEP = 1
"""Default key frames of the train split: every frame from ``FIRST_KEY`` on (13 of a 20-frame clip)."""
EVAL_KEY_STEP = 3
"""Default key frames of the val, test and challenging splits: frames 8, 11, 14, 17, 20 of a 20-frame clip."""
FIRST_KEY = 7
"""0-based index of the earliest frame that may be a key frame: every key frame has >= 7 history frames, enough
for the paper's longest clips (5 frames) and the 8-frame ones some video detectors use."""
TEMPORAL_LABELS = "challenging-frames.json"
"""Label file of every frame from the ``FIRST_KEY + 1``-th of the first `TEMPORAL_CLIPS_PER_FACTOR` challenging clips
of each factor, oldest first: what the temporal stability metrics (Rs / Rj / Rm) score, frame after frame."""
TEMPORAL_CLIPS_PER_FACTOR = 4
"""Challenging clips of each factor whose every frame `TEMPORAL_LABELS` holds."""
VISIBILITY_DIR = "visibility"
"""Folder of a set's visibility files: ``visibility/<split>.json``, one line per key frame of ``<split>.json``
(``raw_file``, ``visibility``: per lane, per h_sample, the mask of `stamlane.synth.visibility.paint_visibility`)."""
REVEAL_FRAMES = 12
"""Frames of a clip of the reveal splits (the key frame last): room for spans up to 8 frames, or 4 at stride 3."""


def key_frames(num_frames: int, key_step: int = 0) -> list[int]:
    """0-based indices of a clip's labelled key frames, oldest first.

    Args:
        num_frames: frames in the clip.
        key_step: 0: the last frame only; k >= 1: the last frame and every k-th frame before it, not before
            ``FIRST_KEY`` (a clip of at most ``FIRST_KEY + 1`` frames has only its last frame as key).
    """
    if key_step < 0:
        raise ValueError(f"key_step must be >= 0, got {key_step}")
    last = num_frames - 1
    if key_step == 0:
        return [last]
    return list(range(last, min(FIRST_KEY, last) - 1, -key_step))[::-1]
