"""The data options, each declared once, in four groups (the ``data:`` section of a config).

- `ClipOptions` (``data.clip``): how a clip is read and resized, what the network sees; shared by `ClipDataModule`
  and `FramesDataModule`, linked into the model (``num_frames``, ``image_size``, ``crop_top``), read back from a
  checkpoint by the streaming predictor.
- `AugmentOptions` (``data.augment``): the training augmentation, one draw per clip.
- `SynthOptions` (``data.synth``): the synthetic set generated when ``data.root`` is null (a `SplitCounts`: its
  clips per split, and how it is made; the default `DEMO_SYNTH`).
- `LoaderOptions` (``data.loader``): batches and worker processes, of both DataModules.

On the command line a field is ``--data.<group>.<field>`` (``--data.clip.num_frames 2``); in YAML::

    data:
      clip: {num_frames: 4, image_size: [80, 256], crop_top: 0.4, align: fly}
      loader: {batch_size: 4, num_workers: 1}

What belongs to one labelled dataset (``root``, ``format``, label files, ``label_dir``, ``thickness``,
``on_error``, ``history_source``) stays a plain argument of `ClipDataModule`. Each group is a frozen dataclass
that checks its values when it is made, so a bad option fails when the config is read, not in the first epoch.
Configs written before the groups existed (flat ``data.num_frames`` ...) are read by `stamlane.training.compat`.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

from stamlane.align.homography import align_preset
from stamlane.data.alignment import ALIGN_MODES, ALIGN_STRATEGIES, WARP_MODES
from stamlane.data.corruption import DEFAULT_KINDS, KeyFrameCorruption
from stamlane.data.frame_store import DEFAULT_MEMORY_MB
from stamlane.data.transforms import ClipTransform
from stamlane.safety.budget import check_clip, check_size, check_workers
from stamlane.synth.config import SynthConfig
from stamlane.synth.layout import DEMO_SPLITS, EVAL_KEY_STEP, TRAIN_KEY_STEP, SplitCounts

__all__ = ["DEMO_SYNTH", "GROUPS", "AugmentOptions", "ClipOptions", "LoaderOptions", "SynthOptions", "checked_strides"]


def _pair(value: tuple[float, float] | list[float], kind: type, name: str) -> tuple[Any, Any]:
    """``value`` as a tuple of two ``kind`` (YAML gives lists)."""
    if len(value) != 2:
        raise ValueError(f"{name} must have two values, got {value}")
    return (kind(value[0]), kind(value[1]))


def checked_strides(strides: tuple[int, ...] | list[int]) -> tuple[int, ...]:
    """``strides`` (a spacing mix, `AugmentOptions.strides`) as a tuple of ints, each >= 1."""
    values = tuple(int(s) for s in strides)
    if any(s < 1 for s in values):
        raise ValueError(f"strides must all be >= 1, got {list(values)}")
    return values


@dataclass(frozen=True)
class ClipOptions:
    """How a clip is read and resized: what the network sees, the same in training, evaluation and prediction.

    Every clip dataset takes it whole (`stamlane.data.clips.ClipDataset`'s ``clip``): these options are declared,
    defaulted and checked here alone. `ClipDataModule` and `FramesDataModule` read clips with it; ``num_frames``,
    ``image_size`` and ``crop_top`` are linked into the model (``model.num_frames`` ...), so that a checkpoint carries them to ``stamlane stream``.

    Attributes:
        num_frames: frames per clip T >= 1, key frame last (the paper: 4 on TuSimple, 2 on ApolloScape).
        stride: distance between clip frames >= 1, in frame numbers (30 for CULane's stored frames), or in
            positions of the sorted listing (ApolloScape, a folder of frames).
        image_size: network input ``(H, W)``, pixels.
        crop_top: fraction of the frame height cut off at the top (sky) before resizing to ``image_size``, in
            ``[0, 0.9)``, in every split (`stamlane.data.transforms.ClipTransform`).
        align: where each history frame's ``key_from_hist`` comes from (`stamlane.data.alignment.ALIGN_MODES`):
            ``"fly"`` (the paper's ORB pre-alignment, estimated per clip and memoised), ``"cache"`` (``stamlane
            align`` output in ``cache_dir``), ``"none"`` (identity) or ``"true"`` (the synthetic generator's exact
            homographies, an oracle for experiments). A folder or a video (``--source``) aligns ``"fly"`` or
            ``"none"``.
        warp: where that alignment is applied (`stamlane.data.alignment.WARP_MODES`): ``"image"`` (history frames
            warped onto the key frame before the network, the paper's pre-alignment) or ``"feature"`` (frames
            unwarped, the homographies in network pixels in the batch as ``key_from_hist_net``; the model warps
            the history FEATURES, as the streaming predictor does: train with it for streaming).
        cache_dir: the alignment cache folder for ``align="cache"``.
        horizon_row: first ground row, original pixels, for ``align="fly"`` (None: ``stamlane.align``'s default).
        align_strategy: ``"chain"`` (consecutive frames matched and multiplied) or ``"direct"`` (each history frame
            against the key frame) for ``align="fly"``.
        align_preset: the ORB settings of ``align="fly"`` (and of the pairs ``"cache"`` misses), a name of
            `stamlane.align.homography.ALIGN_PRESETS`: ``"standard"`` (what every shipped model was made with) or
            ``"fast"`` (faster estimates, same accuracy on real-frame pairs, other homographies: opt in;
            measured in docs/alignment.md).
        repeat_missing_history: a history frame that does not exist is replaced by the nearest later one instead
            of making the clip bad (sets such as CULane, whose early frames may lack).
    """

    num_frames: int = 4
    stride: int = 1
    image_size: tuple[int, int] = (128, 256)
    crop_top: float = 0.0
    align: str = "fly"
    warp: str = "image"
    cache_dir: str | None = None
    horizon_row: int | None = None
    align_strategy: str = "chain"
    align_preset: str = "standard"
    repeat_missing_history: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "image_size", _pair(self.image_size, int, "image_size"))
        if self.num_frames < 1:
            raise ValueError(f"num_frames must be >= 1, got {self.num_frames}")
        if self.stride < 1:
            raise ValueError(f"stride must be >= 1, got {self.stride}")
        if self.align not in ALIGN_MODES:
            raise ValueError(f"align must be one of {ALIGN_MODES}, got {self.align!r}")
        if self.warp not in WARP_MODES:
            raise ValueError(f"warp must be one of {WARP_MODES}, got {self.warp!r}")
        if self.align_strategy not in ALIGN_STRATEGIES:
            raise ValueError(f"align_strategy must be one of {ALIGN_STRATEGIES}, got {self.align_strategy!r}")
        align_preset(self.align_preset)  # one line naming the presets
        self.transform()  # ClipTransform checks image_size and crop_top
        check_clip(self.num_frames, self.image_size, "data.clip")  # the size budget, before any clip is read

    def transform(self) -> ClipTransform:
        """The evaluation and prediction transform: the sky cut and the resize to ``image_size``, no augmentation."""
        return ClipTransform(self.image_size, crop_top=self.crop_top)


@dataclass(frozen=True)
class AugmentOptions:
    """The training augmentation, one random draw per clip applied to every frame alike (validation, test and
    prediction only resize).

    Attributes:
        crop_scale: range of the crop side as a fraction of the frame side (both axes alike, aspect ratio kept);
            ``(1, 1)``: no crop.
        flip_prob: chance of a horizontal flip (lane order mirrored), in ``[0, 1]``.
        brightness: brightness factor drawn from ``[1 - brightness, 1 + brightness]``, in ``[0, 1)``.
        contrast: contrast factor drawn from ``[1 - contrast, 1 + contrast]``, in ``[0, 1)``.
        saturation: saturation factor drawn from ``[1 - saturation, 1 + saturation]``, in ``[0, 1)``.
        hue: hue shift drawn from ``[-hue, hue]``, in fractions of a full turn (<= 0.5).
        key_corruption: chance that a training sample's key frame alone is corrupted, history intact
            (`stamlane.data.corruption.KeyFrameCorruption`: dropped regions, glare, occluders, a blanked near
            road); 0: never.
        key_corruption_kinds: the kinds drawn from (`stamlane.data.corruption.CORRUPTIONS`).
        strides: a mix of frame spacings for training clips: each training key frame is read at one of these
            strides instead of ``clip.stride``, the same one in every epoch and process
            (`stamlane.data.clips.mixed_stride`: a hash of its path), e.g. ``[1, 4]``: 20 fps and 5 fps spacing
            from one 20 fps set (with ``clip.repeat_missing_history`` for the key frames near a clip's start);
            empty: ``clip.stride``. Validation, test and prediction read ``clip.stride``, which the checkpoint
            records.
    """

    crop_scale: tuple[float, float] = (0.85, 1.0)
    flip_prob: float = 0.5
    brightness: float = 0.2
    contrast: float = 0.2
    saturation: float = 0.2
    hue: float = 0.0
    key_corruption: float = 0.0
    key_corruption_kinds: tuple[str, ...] = DEFAULT_KINDS
    strides: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "crop_scale", _pair(self.crop_scale, float, "crop_scale"))
        object.__setattr__(self, "key_corruption_kinds", tuple(self.key_corruption_kinds))
        object.__setattr__(self, "strides", checked_strides(self.strides))
        self.transform(ClipOptions())  # ClipTransform checks the geometry and the colour jitter
        KeyFrameCorruption(self.key_corruption, self.key_corruption_kinds)  # checked even when unused

    def transform(self, clip: ClipOptions) -> ClipTransform:
        """The training transform of clips read as ``clip`` says: its sky cut and size, then this augmentation."""
        return ClipTransform(
            clip.image_size,
            crop_top=clip.crop_top,
            crop_scale=self.crop_scale,
            flip_prob=self.flip_prob,
            brightness=self.brightness,
            contrast=self.contrast,
            saturation=self.saturation,
            hue=self.hue,
        )

    def corruption(self) -> KeyFrameCorruption | None:
        """The key-frame corruption of training samples, None when ``key_corruption`` is 0."""
        return KeyFrameCorruption(self.key_corruption, self.key_corruption_kinds) if self.key_corruption > 0 else None


@dataclass(frozen=True)
class SynthOptions(SplitCounts):
    """The synthetic set `ClipDataModule` generates (with a progress bar) when ``data.root`` is null and
    ``data/synthetic-v<format>`` is missing; the arguments of `stamlane.synth.generate_dataset`.

    Its clips per split are the fields of `stamlane.synth.layout.SplitCounts`, declared and checked there alone
    (``data.synth.train``, ``data.synth.reveal_traffic``, ...: a new split's count is a key here with no line of
    this class); like ``SplitCounts()``, ``SynthOptions()`` has no clip. The DataModule's default is `DEMO_SYNTH`,
    the demo's set (`stamlane.synth.layout.DEMO_SPLITS`), and a config or a flag that names some counts
    (``--data.synth.train 8``) keeps the others of that default.

    Attributes:
        train_key_step: labelled key frames per train clip (`stamlane.synth.layout.key_frames`: 0 = the last
            frame only, 1 = every frame from the 8th, 3 = frames 8, 11, .., 20).
        eval_key_step: labelled key frames per clip of the val, test and challenging splits (as ``train_key_step``).
        seed: master seed of the set.
        size: frame size ``(H, W)``, pixels.
    """

    train_key_step: int = TRAIN_KEY_STEP
    eval_key_step: int = EVAL_KEY_STEP
    seed: int = 0
    size: tuple[int, int] = (SynthConfig.height, SynthConfig.width)

    def __post_init__(self) -> None:
        object.__setattr__(self, "size", _pair(self.size, int, "size"))
        try:
            super().__post_init__()  # the counts, checked by SplitCounts
        except ValueError as err:
            raise ValueError(f"synth: {err}") from None
        for name in ("train_key_step", "eval_key_step"):
            if getattr(self, name) < 0:
                raise ValueError(f"synth.{name} must be >= 0, got {getattr(self, name)}")
        if min(self.size) < 1:
            raise ValueError(f"synth.size must be (H, W) with positive sides, got {self.size}")
        check_size(self.size, "data.synth.size")
        self.config()  # the generator's size budget (`stamlane.safety.budget`), checked when the config is read

    def as_dict(self) -> dict[str, int]:
        """The clip counts alone by field name (`SplitCounts.as_dict`: the other options are no split's)."""
        return {f.name: getattr(self, f.name) for f in fields(SplitCounts)}

    def splits(self) -> SplitCounts:
        """Clips per split (`stamlane.synth.dataset.generate_dataset`'s; ``dataset.json`` records them as a dict)."""
        return SplitCounts(**self.as_dict())

    def config(self) -> SynthConfig:
        """The generator's settings of the set (its frame size; the rest the generator's defaults)."""
        return SynthConfig(width=self.size[1], height=self.size[0])


_DEMO_COUNTS: dict[str, Any] = DEMO_SPLITS.as_dict()  # keywords of SynthOptions: SplitCounts' fields
DEMO_SYNTH = SynthOptions(**_DEMO_COUNTS)
"""The demo's set (``stamlane demo``, ``stamlane synth --demo``): `ClipDataModule`'s default ``data.synth``."""


@dataclass(frozen=True)
class LoaderOptions:
    """How clips are batched.

    Attributes:
        batch_size: clips per batch (>= 1).
        num_workers: DataLoader worker processes (>= 0; 0 loads in the main process).
        memory_mb: MiB of this process kept for evaluation frames decoded, aligned and resized once and read again
            by every later pass, probe and model on them (`stamlane.data.frame_store`; the same tensors bit for
            bit); 0: every pass reads and resizes its frames afresh.
    """

    batch_size: int = 4
    num_workers: int = 0
    memory_mb: int = DEFAULT_MEMORY_MB

    def __post_init__(self) -> None:
        if self.batch_size < 1:
            raise ValueError(f"batch_size must be >= 1, got {self.batch_size}")
        if self.num_workers < 0:
            raise ValueError(f"num_workers must be >= 0, got {self.num_workers}")
        check_workers(self.num_workers, "data.loader.num_workers")
        if self.memory_mb < 0:
            raise ValueError(f"memory_mb must be >= 0, got {self.memory_mb}")


GROUPS: dict[str, type] = {
    "clip": ClipOptions,
    "augment": AugmentOptions,
    "synth": SynthOptions,
    "loader": LoaderOptions,
}
"""The option groups by their key in the ``data:`` section."""
