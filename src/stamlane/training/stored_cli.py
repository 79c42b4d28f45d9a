"""``stamlane predict|validate|test --ckpt_path CKPT [options]``: a stored model run without a config.

The checkpoint (a file, a run folder or a shipped model's name) is opened once as a
`stamlane.training.stored.StoredModel`; its run's config gives every option's default, the options typed replace
them, and the command is a plain ``lightning.Trainer.predict`` (`stamlane.training.stored_predict`), ``validate`` or
``test`` of the module as it was opened (the checkpoint is not read again). The options are those of the command
that a stored model can take, with LightningCLI's names:

- ``--data.*``: the data module (`stamlane.data.datamodule.ClipDataModule`: ``--data.root``,
  ``--data.predict_labels``, ``--data.history_source``, ``--data.clip.*``, ``--data.loader.*``, ...);
- ``--trainer.*``: ``lightning.Trainer`` options (one process unless ``--trainer.devices`` and the like are given:
  `stamlane.training.stored_predict.prediction_trainer_options`);
- ``--model.postprocess.*``, ``--model.report_run_time``, ``--model.bf16``: the decoding, the run times handed to
  the TuSimple file, bfloat16;
- ``--seed_everything`` (the run's seed), ``--weights_only`` (a stored model is always read with
  ``weights_only=True``: ``false`` is refused; a foreign checkpoint goes with ``--config``);
- predict: ``--source`` (a folder of frames or a video instead of the data split,
  `stamlane.data.datamodule.FramesDataModule`, read with the run's clip and loader options) and ``--predictions.*``
  (the lane writer, `stamlane.predict.prediction_writer.LanePredictionWriter`); a prediction logs nothing unless
  ``--trainer.logger true``;
- validate, test: ``--eval.*`` (the metrics, `stamlane_eval.integrations.lightning.LaneEvalCallback`); the run's
  logger logs under ``<name>-validate`` / ``<name>-test`` beside the run's logs (under ``--trainer.default_root_dir``
  when that is given and the logger's folder is not), and its callbacks run but for checkpoints and learning rates.

Any other option (``--model.encoder...``: another network) needs ``--config`` (`stamlane.training.lightning_cli`).
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from dataclasses import asdict, replace
from typing import Any

__all__ = ["COMMANDS", "RENAMED_LOGGERS", "build_parser", "main_stored", "parse", "scoring_name"]

COMMANDS = ("predict", "validate", "test")
"""The commands a stored model runs here."""

_TRAINER_SKIPPED = {"enable_checkpointing", "plugins", "profiler", "model_registry"}
"""``lightning.Trainer`` options a stored model's command sets itself (no checkpoints) or never takes."""

RENAMED_LOGGERS = ("CSVLogger", "TensorBoardLogger", ".RunLogger")
"""The loggers whose ``name`` validate and test extend (`scoring_name`): their folder is ``save_dir/name``, and a
training run's own would gain a ``version_N`` of scores."""


def _flat(prefix: str, value: Any) -> dict[str, Any]:
    """``{"data": {"clip": {"num_frames": 4}}}`` -> ``{"data.clip.num_frames": 4}`` (lists and classes kept)."""
    if not isinstance(value, Mapping) or "class_path" in value:
        return {prefix: value}
    out: dict[str, Any] = {}
    for key, item in value.items():
        out |= _flat(f"{prefix}.{key}", item)
    return out


def scoring_name(name: str | None, command: str) -> str:
    """The logger name of ``command``'s (validate, test) scores: ``<name>-<command>`` (``lightning_logs-<command>``
    without a name); a name that already ends so is kept (``stam4-test`` stays ``stam4-test``)."""
    name = name or "lightning_logs"
    return name if name.endswith(f"-{command}") else f"{name}-{command}"


def _scoring_logger(logger: Any, command: str) -> Any:
    """The run's stored logger option for ``command`` (validate, test): each CSV or TensorBoard logger named by
    `scoring_name`; any other value as stored."""
    from stamlane.training.run_logger import each_logger

    logger = copy.deepcopy(logger)
    for one in each_logger(logger):
        if isinstance(one, dict) and str(one.get("class_path", "")).endswith(RENAMED_LOGGERS):
            init = one.setdefault("init_args", {})
            init["name"] = scoring_name(init.get("name"), command)
    return logger


def build_parser(model: Any, command: str = "predict") -> Any:
    """The parser of ``stamlane COMMAND --ckpt_path`` for ``model`` (a `StoredModel`): every default its run's (a
    data root recorded relative to the folder the run was started in: where it is found, `stamlane.training.stored.
    data_root`)."""
    from jsonargparse import ArgumentParser
    from lightning.pytorch import Callback, Trainer
    from stamlane_eval.integrations.lightning import LaneEvalCallback

    from stamlane.data.datamodule import ClipDataModule
    from stamlane.data.labels import DataError
    from stamlane.predict.postprocess import PostprocessConfig
    from stamlane.predict.prediction_writer import LanePredictionWriter
    from stamlane.training.stored import data_root
    from stamlane.training.stored_predict import prediction_trainer_options

    parser = ArgumentParser(
        prog=f"stamlane {command}", exit_on_error=False, allow_abbrev=False, description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("--ckpt_path", type=str, required=True, help="a checkpoint, a run folder or a shipped name")
    parser.add_argument("--source", type=str | None, default=None, help="predict: a folder of frames or a video file")
    seed = (model.config or {}).get("seed_everything", 0)
    parser.add_argument("--seed_everything", type=bool | int, default=seed, help="seed_everything first")
    parser.add_argument("--weights_only", type=bool | None, default=None, help="always true for a stored model")
    parser.add_class_arguments(ClipDataModule, "data")
    stored = model.section("trainer")
    if command == "predict":
        parser.add_class_arguments(LanePredictionWriter, "predictions")
        skipped = _TRAINER_SKIPPED | {"callbacks", "logger"}
        parser.add_class_arguments(Trainer, "trainer", instantiate=False, skip=skipped)
        parser.add_argument("--trainer.logger", type=bool, default=False, help="Lightning's default logger, if true")
        parser.add_argument("--trainer.callbacks", type=list[Callback] | None, default=None, help="besides the writer")
        trainer = prediction_trainer_options(stored)
    else:
        parser.add_class_arguments(LaneEvalCallback, "eval")
        parser.add_class_arguments(Trainer, "trainer", instantiate=False, skip=_TRAINER_SKIPPED)
        trainer = prediction_trainer_options(stored, keep=None)
        if "logger" in trainer:
            trainer["logger"] = _scoring_logger(trainer["logger"], command)
    module = model.module
    parser.add_class_arguments(PostprocessConfig, "model.postprocess")
    parser.add_argument("--model.report_run_time", type=bool, default=bool(module.report_run_time))
    parser.add_argument("--model.bf16", type=bool, default=bool(module.bf16))
    known = set(parser.get_defaults().keys())
    defaults = _flat("data", model.data) | _flat("trainer", trainer)
    defaults |= _flat("predictions", model.section("predictions")) | _flat("eval", model.section("eval"))
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


def parse(model: Any, args: list[str], command: str = "predict") -> tuple[Any, Any]:
    """``args`` parsed over ``model``'s defaults (`build_parser`): ``(config, its classes instantiated)``.

    Raises:
        ArgumentError: an option that does not parse.
    """
    from stamlane.safety.paths import check_config_paths
    from stamlane.training.compat import check_flags

    check_flags(args)  # --data.num_frames: one line naming --data.clip.num_frames
    parser = build_parser(model, command)
    config = parser.parse_args(args)
    check_config_paths(config.as_dict())  # the paths named, through the gate of the flags' paths, before any is used
    if command != "predict":
        _logs_follow_root(config, model.section("trainer"))
    instantiate = getattr(parser, "instantiate", None) or parser.instantiate_classes
    return config, instantiate(config)


def _logs_follow_root(config: Any, stored: Mapping[str, Any]) -> None:
    """A ``--trainer.default_root_dir`` other than the run's moves each logger whose folder is still the run's there
    too: the logs of a validation given its own root land under it, not beside the run's."""
    from stamlane.training.run_logger import each_logger

    root = config.trainer.default_root_dir
    if root is None or root == stored.get("default_root_dir"):
        return
    logger, kept = config.trainer.logger, stored.get("logger")
    kept_dirs = {str(one.get("init_args", {}).get("save_dir")) for one in each_logger(kept) if isinstance(one, dict)}
    for one in each_logger(logger):
        init = getattr(one, "init_args", None)
        if init is not None and "save_dir" in init and str(init["save_dir"]) in kept_dirs:
            init["save_dir"] = root


def main_stored(args: list[str], command: str = "predict") -> None:
    """Run ``stamlane COMMAND --ckpt_path CKPT ...`` (``args`` after the subcommand, the shipped names resolved).

    Raises:
        ArgumentError: an option that does not parse.
        CheckpointError: the checkpoint refused.
        GuardError, DataError, ValueError: an output among the inputs, bad data, a folder of another source's results.
    """
    from stamlane.training.stored import StoredModel, data_root

    model = StoredModel.open(_ckpt(args))  # the one read of the checkpoint
    config, init = parse(model, args, command)
    if config.weights_only is False:
        raise ValueError("--weights_only false: a stored model is read with weights_only=True; give --config CONFIG")
    if config.source and command != "predict":
        raise ValueError("--source is for predict only")
    if not config.source and config.data.root is not None and config.data.root == model.data.get("root"):
        data_root(config.data.root, model.start_dir, model.checkpoint)  # found nowhere: the line naming the flag
    module = model.module
    module.postprocess = init.model.postprocess
    module.report_run_time, module.bf16 = config.model.report_run_time, config.model.bf16
    trainer = {k: v for k, v in config.trainer.as_dict().items() if v is not None and k not in ("callbacks", "logger")}
    callbacks = list(init.trainer.callbacks or [])
    if command == "predict":
        _predict(model, config, init, callbacks, trainer)
    else:
        _score(command, model, config, init, callbacks, trainer)


def _predict(model: Any, config: Any, init: Any, callbacks: list[Any], trainer: dict[str, Any]) -> None:
    """``Trainer.predict`` of the split or ``--source`` into the lane writer's folder."""
    from stamlane.data.datamodule import FramesDataModule
    from stamlane.training.lightning_cli import checkpoint_name
    from stamlane.training.stored_predict import (
        check_prediction_outputs,
        name_predictions,
        predict_stored,
        warn_sequence,
    )

    data, writer, source = init.data, init.predictions, config.source
    if source:  # read as the model was trained; a folder has no alignment cache nor true homographies: ORB on the fly
        clip = data.clip if data.clip.align in ("fly", "none") else replace(data.clip, align="fly", cache_dir=None)
        data = FramesDataModule(source, clip, data.loader, history_source=data.history_source)
    name_predictions(writer, data, source, checkpoint_name(str(model.checkpoint), []))
    check_prediction_outputs(
        writer, [getattr(data, "root", None), source], [model.checkpoint], folders=[trainer.get("default_root_dir")]
    )
    if source:
        warn_sequence(data, say=_first_process())
    logger = init.trainer.logger
    predict_stored(model, data, writer, seed=config.seed_everything, callbacks=callbacks, logger=logger, **trainer)


def _score(command: str, model: Any, config: Any, init: Any, callbacks: list[Any], trainer: dict[str, Any]) -> None:
    """``Trainer.validate`` or ``test`` of the split with the metrics of ``eval``, and the line saying where they
    were logged."""
    from lightning.pytorch import Trainer
    from lightning.pytorch.callbacks import LearningRateMonitor, ModelCheckpoint

    from stamlane.safety.guard import check_outputs
    from stamlane.training.stored_predict import seed_run

    data = init.data
    kept = [cb for cb in callbacks if not isinstance(cb, (ModelCheckpoint, LearningRateMonitor))]  # fit's
    runner = Trainer(callbacks=[*kept, init.eval], logger=init.trainer.logger, enable_checkpointing=False, **trainer)
    folders = [runner.default_root_dir, *(lg.save_dir for lg in runner.loggers if getattr(lg, "save_dir", None))]
    check_outputs([], [data.root, model.checkpoint], folders=folders, protected=[data.root])
    seed_run(config.seed_everything)
    getattr(runner, command)(model.module, datamodule=data)
    if runner.is_global_zero and runner.logger is not None and runner.logger.log_dir:
        print(f"stamlane {command}: metrics logged under {runner.logger.log_dir}", flush=True)


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
