"""A stored model, opened once: the one way to run a checkpoint, a run folder or a shipped model outside training.

`StoredModel.open` takes what a user names (a checkpoint file, a run folder ``RUN`` with ``RUN/checkpoints/last.ckpt``,
or a shipped model's name, `stamlane.weights`), reads the checkpoint ONCE within the budget
(`stamlane.safety.checkpoints.read_checkpoint`, ``weights_only=True``), builds the network from the closed registry
(`stamlane.training.registry.build_module`: CPU, eval mode), checks the data options it carries and reads them in
today's names (`stamlane.training.compat.clip_options`), and keeps how the model was trained to see frames as one
typed record, `ModelSettings`. Everything that runs a stored model reads these settings, never its own defaults::

    from stamlane.stream import StreamingPredictor
    from stamlane.training.stored import StoredModel

    model = StoredModel.open("stam4-dashcam")           # or "RUN/checkpoints/last.ckpt", or "RUN"
    predictor = StreamingPredictor.from_stored(model)   # T, size, crop, alignment (on/off, preset, horizon), decoding
    lanes = predictor(bgr_image).lanes                  # per frame, in order

``stamlane stream``, ``stamlane export`` and the benchmarks open models here; the settings of one checkpoint are the
same on every route (tests/training/test_stored.py).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from stamlane.data.datamodule import ClipDataModule
    from stamlane.data.options import ClipOptions
    from stamlane.predict.postprocess import PostprocessConfig
    from stamlane.training.module import StamLaneModule

__all__ = ["ModelSettings", "StoredModel", "checkpoint_of", "data_root"]

RUN_CHECKPOINT = Path("checkpoints") / "last.ckpt"
"""The final weights of a run folder (what ``stamlane fit`` writes and `stamlane.training.runs.open_run` opens)."""


@dataclass(frozen=True)
class ModelSettings:
    """How a stored model was trained to see frames and how it decodes lanes: what every route that runs it uses.

    Attributes:
        num_frames: T, frames fused (key frame last).
        image_size: the network input ``(H, W)``, pixels, after the cut and the resize.
        crop_top: fraction of the frame's rows cut at the top before resizing.
        aligns: whether the history is aligned onto the key frame (False for a model trained with ``align: none``).
        align_preset: the ORB settings of the alignment (`stamlane.align.homography.ALIGN_PRESETS`).
        horizon_row: the first ground row of the alignment, original pixels (None: `stamlane.align`'s default).
        bf16: whether the network runs under bfloat16 autocast, as trained.
        postprocess: the lane decoding settings (DBSCAN and sampling).
        clip: the data options as stored (None for a checkpoint that records none: the settings above then come from
            the module's own record and the defaults of `stamlane.data.options.ClipOptions`).
    """

    num_frames: int
    image_size: tuple[int, int]
    crop_top: float
    aligns: bool
    align_preset: str
    horizon_row: int | None
    bf16: bool
    postprocess: PostprocessConfig
    clip: ClipOptions | None = field(default=None, compare=False)

    @classmethod
    def of(cls, module: Any, clip: ClipOptions | None) -> ModelSettings:
        """The settings of a built module and its stored data options (the module's record of T and the size first,
        then the data options'; the data options' crop, which cut the frames it saw, before the module's record).

        Raises:
            ValueError: neither records T or the input size.
        """
        from stamlane.data.options import ClipOptions

        hparams = getattr(module, "hparams", {})
        num_frames = getattr(module, "num_frames", None) or (clip.num_frames if clip is not None else None)
        image_size = hparams.get("image_size") or (clip.image_size if clip is not None else None)
        if num_frames is None or image_size is None:
            raise ValueError("the model records no num_frames / image_size")
        crop_top = clip.crop_top if clip is not None else hparams.get("crop_top") or 0.0
        data = clip if clip is not None else ClipOptions(num_frames=int(num_frames), image_size=tuple(image_size))
        return cls(
            num_frames=int(num_frames),
            image_size=(int(image_size[0]), int(image_size[1])),
            crop_top=float(crop_top),
            aligns=data.align != "none",
            align_preset=data.align_preset,
            horizon_row=data.horizon_row,
            bf16=bool(getattr(module, "bf16", False)),
            postprocess=module.postprocess,
            clip=clip,
        )


@dataclass(frozen=True)
class StoredModel:
    """A model opened from storage (see the module docstring): its network and the settings it was trained with.

    Attributes:
        checkpoint: the checkpoint file that was read.
        module: the `StamLaneModule`, built from the closed registry, on the CPU, in eval mode.
        settings: how it sees frames and decodes lanes (`ModelSettings`).
        config: the run's config as plain data, checked against the registry in today's names, when the checkpoint
            carries one (None for a checkpoint of before configs travelled in them).
        data: the options of its data module, in today's names (the run config's ``data`` section, else the
            checkpoint's data hyper-parameters; empty when it records neither): what `datamodule` builds.
        start_dir: the folder ``stamlane fit`` was started in (its relative paths are relative to it), if recorded.
    """

    checkpoint: Path
    module: StamLaneModule = field(repr=False)
    settings: ModelSettings
    config: dict[str, Any] | None = field(default=None, repr=False)
    data: dict[str, Any] = field(default_factory=dict, repr=False)
    start_dir: str | None = None

    @classmethod
    def open(cls, where: str | Path) -> StoredModel:
        """Open a checkpoint file, a run folder or a shipped model's name (`checkpoint_of`), reading the file once.

        Raises:
            CheckpointError: no such checkpoint, one over the budget or unreadable, or one whose network, data
                options or config the registry refuses (one line naming the file).
        """
        from stamlane.safety.checkpoints import read_checkpoint
        from stamlane.training.lightning_cli import CONFIG_KEY

        path = checkpoint_of(where)
        content = read_checkpoint(path)
        beside = config_beside(path) if not isinstance(content.get(CONFIG_KEY), str) else None
        return cls.of_content(path, content, beside)

    @classmethod
    def of_content(cls, path: Path, content: dict[str, Any], beside: tuple[Path, str] | None = None) -> StoredModel:
        """The stored model of a checkpoint's content, already read from ``path`` (by `open`, or by
        `stamlane.training.runs.open_run`, which reads it for the run's config): the file is not read again.
        ``beside``: the run's config where the checkpoint carries none (`config_beside`: its file and text).

        Raises:
            CheckpointError: see `open`.
        """
        from stamlane.safety.checkpoints import CheckpointError
        from stamlane.training.compat import clip_options, group_data
        from stamlane.training.lightning_cli import CONFIG_KEY, START_DIR_KEY
        from stamlane.training.registry import build_module, check_data_hparams, check_run_config

        text = content.get(CONFIG_KEY)  # the run's config first: what it names is refused before anything is built
        config = check_run_config(text, path) if isinstance(text, str) else None
        if config is None and beside is not None:
            config = check_run_config(beside[1], beside[0])
        module = build_module(content, path)
        data = content.get("datamodule_hyper_parameters")
        if data is not None:
            check_data_hparams(data, path)
        if not isinstance(data, dict) and config is not None and isinstance(config.get("data"), dict):
            data = config["data"]  # no data hyper-parameters stored: the run config's data section says the same
        # the data module of a prediction: the run's config, what `stamlane fit` read (else the data hyper-parameters)
        run_data = config["data"] if config is not None and isinstance(config.get("data"), dict) else data
        try:
            clip = clip_options(data) if isinstance(data, dict) else None
            settings = ModelSettings.of(module, clip)
            grouped = group_data(run_data) if isinstance(run_data, dict) else {}
        except ValueError as err:
            raise CheckpointError(f"checkpoint {path}: {err}") from None
        start = content.get(START_DIR_KEY)
        options = {k: v for k, v in grouped.items() if not str(k).startswith("_")}
        return cls(path, module, settings, config, options, start if isinstance(start, str) else None)

    def section(self, name: str) -> dict[str, Any]:
        """A section of the run's config (``trainer``, ``predictions``, ...) as plain data; empty without one."""
        value = (self.config or {}).get(name)
        return dict(value) if isinstance(value, dict) else {}

    def datamodule(self, **options: Any) -> ClipDataModule:
        """The run's data module (`stamlane.data.datamodule.ClipDataModule`, its stored data options in today's
        names), each of ``options`` replacing its option: ``root``, ``predict_labels``, ``history_source``, or an
        option group (``clip=ClipOptions(...)``) or a mapping of some of a group's options (``clip={"align":
        "true"}``).

        Raises:
            ValueError: an option the data module refuses.
        """
        from stamlane.data.datamodule import ClipDataModule
        from stamlane.data.options import GROUPS
        from stamlane.training.typed_values import build_value, parameter_hints

        hints, names = parameter_hints(ClipDataModule)
        stored = {k: v for k, v in self.data.items() if k in names}
        for group, value in options.items():
            if group in GROUPS and isinstance(value, dict):
                options[group] = {**(stored.get(group) or {}), **value}
        kwargs = {k: build_value(v, hints.get(k, Any)) for k, v in {**stored, **options}.items()}
        return ClipDataModule(**kwargs)

    def predict(self, data: Any, writer: Any, **trainer_options: Any) -> None:
        """Predict ``data`` (a LightningDataModule) with this model through a plain ``lightning.Trainer.predict``,
        written by ``writer`` (`stamlane.predict.prediction_writer.LanePredictionWriter`); see
        `stamlane.training.stored_predict.predict_stored`."""
        from stamlane.training.stored_predict import predict_stored

        predict_stored(self, data, writer, **trainer_options)


def checkpoint_of(where: str | Path) -> Path:
    """The checkpoint file a user means: a run folder's ``checkpoints/last.ckpt``, a shipped model's file where
    ``where`` is one's name and no file or folder of that name is here (`stamlane.weights.resolve`), else ``where``.

    Raises:
        CheckpointError: a folder that holds no ``checkpoints/last.ckpt``.
    """
    from stamlane.weights import resolve

    path = Path(resolve(str(where)))
    if path.is_dir():
        if not (path / RUN_CHECKPOINT).is_file():
            from stamlane.safety.checkpoints import CheckpointError  # torch: only on the way out (the CLI's fast lines)

            raise CheckpointError(f"{path} holds no {RUN_CHECKPOINT.as_posix()} (not a finished run folder)")
        return path / RUN_CHECKPOINT
    return path


def config_beside(ckpt: Path) -> tuple[Path, str] | None:
    """The config of the run a checkpoint of before configs travelled in them belongs to: ``RUN/config.yaml`` for
    ``RUN/checkpoints/NAME.ckpt`` (its file and text, read within the config budget); None where there is none.

    Raises:
        CheckpointError: a config there that is no readable file (a FIFO, a device, over the budget).
    """
    source = ckpt.resolve().parent.parent / "config.yaml"
    if ckpt.resolve().parent.name != "checkpoints" or not os.path.lexists(source):
        return None
    from stamlane_eval.cli_tools import check_input_file
    from stamlane_eval.io import read_text

    from stamlane.safety.checkpoints import CheckpointError
    from stamlane.safety.paths import MAX_CONFIG_BYTES

    try:
        check_input_file(source, "run config")
        return source, read_text(source, limit=MAX_CONFIG_BYTES)
    except (OSError, ValueError) as err:
        raise CheckpointError(str(err) if str(source) in str(err) else f"run config {source}: {err}") from None


def data_root(recorded: str | None, start_dir: str | None, ckpt: str | Path) -> Path | None:
    """The data root to give a run that recorded ``recorded`` relative to the folder it was started in
    (``data/synthetic-v7``), so that it works from any folder: looked for under ``start_dir`` (recorded in the
    checkpoints of ``stamlane fit``), then under the ancestors of the checkpoint ``ckpt``'s folder, then here. None
    when the root is absolute or found nowhere but here; a default synthetic set (``recorded`` None) found nowhere is
    generated here, as ``fit`` would.

    Raises:
        DataError: a relative root found nowhere, naming the flag to give.
    """
    from stamlane.data.datamodule import DEFAULT_SYNTHETIC_ROOT
    from stamlane.data.labels import DataError

    root = Path(recorded) if recorded is not None else Path(DEFAULT_SYNTHETIC_ROOT)
    if root.is_absolute():
        return None
    bases = [Path(start_dir)] if start_dir else []
    bases += list(Path(ckpt).resolve().parent.parents)
    for base in bases:
        if base.is_absolute() and (base / root).is_dir():
            return None if (base / root).resolve() == root.resolve() else base / root
    if root.is_dir() or recorded is None:
        return None
    where = f" (the run was started in {start_dir})" if start_dir else ""
    raise DataError(
        f"data root {root} of the run is relative to the folder it was started in{where} and found neither there "
        f"nor beside the run nor here: give --data.root DIR"
    )
