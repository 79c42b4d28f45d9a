"""``stamlane predict --ckpt_path CKPT [--source DIR|VIDEO] [options]``: a stored model's lanes, without a config.

The checkpoint (a file, a run folder or a shipped model's name) is opened once as a
`stamlane.training.stored.StoredModel`; its run's config gives every option's default, the options typed replace
them, and the prediction is a plain ``lightning.Trainer.predict`` (`stamlane.training.stored_predict`). The options
are those of ``stamlane predict`` that a stored model can take, with LightningCLI's names:

- ``--data.*``: the data module (`stamlane.data.datamodule.ClipDataModule`: ``--data.root``,
  ``--data.predict_labels``, ``--data.history_source``, ``--data.clip.*``, ``--data.loader.*``, ...);
- ``--source``: a folder of frames or a video instead of the data split
  (`stamlane.data.datamodule.FramesDataModule`, read with the run's clip and loader options);
- ``--predictions.*``: the lane writer (`stamlane.predict.prediction_writer.LanePredictionWriter`);
- ``--trainer.*``: ``lightning.Trainer`` options of a prediction (one process unless ``--trainer.devices`` and the
  like are given: `stamlane.training.stored_predict.prediction_trainer_options`);
- ``--model.postprocess.*``, ``--model.report_run_time``, ``--model.bf16``: the decoding, the run times handed to
  the TuSimple file, bfloat16;
- ``--seed_everything`` (the run's seed), ``--weights_only`` (a stored model is always read with
  ``weights_only=True``: ``false`` is refused; a foreign checkpoint goes with ``--config``).

Any other option (``--model.encoder...``: another network) needs ``--config`` (`stamlane.training.lightning_cli`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, replace
from typing import Any

__all__ = ["build_parser", "main_stored", "parse"]

_TRAINER_SKIPPED = {"callbacks", "logger", "enable_checkpointing", "plugins", "profiler", "model_registry"}
"""``lightning.Trainer`` options a prediction sets itself: no checkpoints, the writer among its callbacks (others by
``--trainer.callbacks``), a logger only as ``--trainer.logger true`` (Lightning's default; a prediction logs
nothing)."""


def _flat(prefix: str, value: Any) -> dict[str, Any]:
    """``{"data": {"clip": {"num_frames": 4}}}`` -> ``{"data.clip.num_frames": 4}`` (lists and classes kept)."""
    if not isinstance(value, Mapping) or "class_path" in value:
        return {prefix: value}
    out: dict[str, Any] = {}
    for key, item in value.items():
        out |= _flat(f"{prefix}.{key}", item)
    return out


def build_parser(model: Any) -> Any:
    """The parser of ``stamlane predict --ckpt_path`` for ``model`` (a `StoredModel`): every default its run's (a
    data root recorded relative to the folder the run was started in: where it is found, `stamlane.training.stored.
    data_root`)."""
    from jsonargparse import ArgumentParser
    from lightning.pytorch import Callback, Trainer

    from stamlane.data.datamodule import ClipDataModule
    from stamlane.data.labels import DataError
    from stamlane.predict.postprocess import PostprocessConfig
    from stamlane.predict.prediction_writer import LanePredictionWriter
    from stamlane.training.stored import data_root
    from stamlane.training.stored_predict import prediction_trainer_options

    parser = ArgumentParser(
        prog="stamlane predict", exit_on_error=False, allow_abbrev=False, description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("--ckpt_path", type=str, required=True, help="a checkpoint, a run folder or a shipped name")
    parser.add_argument("--source", type=str | None, default=None, help="a folder of frames or a video file")
    seed = (model.config or {}).get("seed_everything", 0)
    parser.add_argument("--seed_everything", type=bool | int, default=seed, help="seed_everything first")
    parser.add_argument("--weights_only", type=bool | None, default=None, help="always true for a stored model")
    parser.add_class_arguments(ClipDataModule, "data")
    parser.add_class_arguments(LanePredictionWriter, "predictions")
    parser.add_class_arguments(Trainer, "trainer", instantiate=False, skip=_TRAINER_SKIPPED)
    parser.add_argument("--trainer.logger", type=bool, default=False, help="Lightning's default logger, if true")
    parser.add_argument("--trainer.callbacks", type=list[Callback] | None, default=None, help="besides the writer")
    module = model.module
    parser.add_class_arguments(PostprocessConfig, "model.postprocess")
    parser.add_argument("--model.report_run_time", type=bool, default=bool(module.report_run_time))
    parser.add_argument("--model.bf16", type=bool, default=bool(module.bf16))
    known = set(parser.get_defaults().keys())
    defaults = _flat("data", model.data) | _flat("predictions", model.section("predictions"))
    defaults |= _flat("trainer", prediction_trainer_options(model.section("trainer")))
    defaults |= _flat("model.postprocess", asdict(module.postprocess))
    defaults["predictions.output_dir"] = None  # the command chooses one per model and source
    recorded = model.data.get("root")
    try:
        found = data_root(recorded if isinstance(recorded, str) else None, model.start_dir, model.checkpoint)
    except DataError:  # said when the split is read from it (`main_stored`): a --source needs no data root
        found = None
    if found is not None:
        defaults["data.root"] = str(found)
    parser.set_defaults({k: v for k, v in defaults.items() if k in known})
    return parser


def parse(model: Any, args: list[str]) -> tuple[Any, Any]:
    """``args`` parsed over ``model``'s defaults (`build_parser`): ``(config, its classes instantiated)``.

    Raises:
        ArgumentError: an option that does not parse.
    """
    from stamlane.training.compat import check_flags

    check_flags(args)  # --data.num_frames: one line naming --data.clip.num_frames
    parser = build_parser(model)
    config = parser.parse_args(args)
    instantiate = getattr(parser, "instantiate", None) or parser.instantiate_classes
    return config, instantiate(config)


def main_stored(args: list[str]) -> None:
    """Run ``stamlane predict --ckpt_path CKPT ...`` (``args`` after the subcommand, the shipped names resolved).

    Raises:
        ArgumentError: an option that does not parse.
        CheckpointError: the checkpoint refused.
        GuardError, DataError, ValueError: an output among the inputs, bad data, a folder of another source's results.
    """
    from stamlane.data.datamodule import FramesDataModule
    from stamlane.safety.paths import check_config_paths
    from stamlane.training.lightning_cli import checkpoint_name
    from stamlane.training.stored import StoredModel, data_root
    from stamlane.training.stored_predict import (
        check_prediction_outputs,
        name_predictions,
        predict_stored,
        warn_sequence,
    )

    model = StoredModel.open(_ckpt(args))  # the one read of the checkpoint
    config, init = parse(model, args)
    if config.weights_only is False:
        raise ValueError("--weights_only false: a stored model is read with weights_only=True; give --config CONFIG")
    check_config_paths(config.as_dict())  # the paths named, through the gate of the flags' paths
    data, writer, source = init.data, init.predictions, config.source
    if source:  # read as the model was trained; a folder has no alignment cache nor true homographies: ORB on the fly
        clip = data.clip if data.clip.align in ("fly", "none") else replace(data.clip, align="fly", cache_dir=None)
        data = FramesDataModule(source, clip, data.loader, history_source=data.history_source)
    elif config.data.root is not None and config.data.root == model.data.get("root"):
        data_root(config.data.root, model.start_dir, model.checkpoint)  # found nowhere: the line naming the flag
    name_predictions(writer, data, source, checkpoint_name(str(model.checkpoint), []))
    trainer = {k: v for k, v in config.trainer.as_dict().items() if v is not None and k != "callbacks"}
    check_prediction_outputs(
        writer, [getattr(data, "root", None), source], [model.checkpoint], folders=[trainer.get("default_root_dir")]
    )
    module = model.module
    module.postprocess = init.model.postprocess
    module.report_run_time, module.bf16 = config.model.report_run_time, config.model.bf16
    if source:
        warn_sequence(data, say=_first_process())
    callbacks = list(init.trainer.callbacks or [])
    predict_stored(model, data, writer, seed=config.seed_everything, callbacks=callbacks, **trainer)


def _ckpt(args: list[str]) -> str:
    """The last ``--ckpt_path`` of ``args``."""
    value = None
    for i, arg in enumerate(args):
        if arg.startswith("--ckpt_path="):
            value = arg.split("=", 1)[1]
        elif arg == "--ckpt_path" and i + 1 < len(args):
            value = args[i + 1]
    if value is None:
        raise ValueError("give --ckpt_path CKPT")
    return value


def _first_process() -> bool:
    """Whether this is the first process of a launcher's (``RANK`` 0, or none)."""
    import os

    return int(os.environ.get("RANK", os.environ.get("LOCAL_RANK", "0")) or 0) == 0
