"""`StamLaneCLI`: LightningCLI for ``stamlane fit|validate|test|predict`` (see ``stamlane.cli``).

A ``--config`` is read in the YAML mode of `stamlane.training.compat.yaml_mode`: a config written by an older
version (the flat data options, a moved class, a renamed option) is read in today's form.
"""

from __future__ import annotations

import dataclasses
import re
import sys
import typing
from dataclasses import replace
from pathlib import Path
from typing import Any

from jsonargparse import ArgumentError, Namespace
from lightning.pytorch import Callback, Trainer
from lightning.pytorch.callbacks import LearningRateMonitor, ModelCheckpoint
from lightning.pytorch.cli import LightningArgumentParser, LightningCLI, SaveConfigCallback
from stamlane_eval.integrations.lightning import LaneEvalCallback

from stamlane.data.datamodule import ClipDataModule, FramesDataModule
from stamlane.predict.prediction_writer import LanePredictionWriter
from stamlane.safety.checkpoints import CheckpointError, read_checkpoint
from stamlane.safety.guard import check_outputs, temporary_name
from stamlane.safety.paths import check_config_paths
from stamlane.training.compat import check_flags, yaml_mode
from stamlane.training.final_checkpoint import FinalCheckpoint
from stamlane.training.fit_report import FitReport, step_of
from stamlane.training.launch import spawned
from stamlane.training.lightning_compat import keep_command_line_hparams, subcommand_parser
from stamlane.training.module import StamLaneModule
from stamlane.training.resume import ExactResume
from stamlane.training.run_logger import each_logger, logs_under_root
from stamlane.training.stored_predict import name_predictions, warn_sequence
from stamlane.training.typed_values import refused_class

__all__ = ["CONFIG_KEY", "START_DIR_KEY", "ConfigInCheckpoint", "StamLaneCLI", "checkpoint_name"]

# registered when this module is imported, not only when a parser is made: the processes of ddp_spawn unpickle the
# trainer (its callbacks are of this module) and save the config with the parser's mode (KeyError otherwise)
yaml_mode()

CONFIG_KEY = "stamlane_config"
"""Checkpoint entry holding the YAML config of the run that wrote it."""
START_DIR_KEY = "stamlane_start_dir"
"""Checkpoint entry holding the folder ``stamlane fit`` was started in (relative paths of the config are relative to
it): ``stamlane validate|test|predict --ckpt_path`` finds the run's data from any folder."""


class ConfigInCheckpoint(Callback):
    """Store the run's YAML config (``CONFIG_KEY``) and the folder it was started in (``START_DIR_KEY``) in every
    checkpoint, so that ``stamlane predict``, ``validate`` and ``test`` work from a checkpoint alone, from any
    folder."""

    def __init__(self, config: str) -> None:
        self.config = config
        self.start_dir = str(Path.cwd())

    def on_save_checkpoint(self, trainer: Trainer, pl_module: Any, checkpoint: dict[str, Any]) -> None:
        checkpoint[CONFIG_KEY] = self.config
        checkpoint[START_DIR_KEY] = self.start_dir


def callbacks_of(trainer: Trainer) -> list[Callback]:
    """The trainer's callbacks, the list itself (Lightning sets ``Trainer.callbacks`` when the trainer is made, without
    declaring it on the class, so a type checker does not see it)."""
    callbacks: list[Callback] = vars(trainer)["callbacks"]
    return callbacks


class StamLaneCLI(LightningCLI):
    """LightningCLI with `StamLaneModule` and ``ClipDataModule``, linked sizes and the lane callbacks.

    Args:
        args: command-line style arguments (``["fit", "--config", ...]``); ``None`` = ``sys.argv``.
        run: run the subcommand (False: only build model, data and trainer).
        report: print where a fit's model went and its best validation F1 (the experiment engine, which reports
            itself, turns it off).
        **kwargs: passed to ``LightningCLI``.
    """

    def __init__(self, args: list[str] | None = None, run: bool = True, report: bool = True, **kwargs: Any) -> None:
        self.report = report
        kwargs.setdefault("seed_everything_default", 0)
        kwargs.setdefault("save_config_kwargs", {"overwrite": True})
        super().__init__(StamLaneModule, ClipDataModule, args=args, run=run, **kwargs)

    def init_parser(self, **kwargs: Any) -> LightningArgumentParser:
        kwargs.setdefault("parser_mode", yaml_mode())  # old configs read in today's names (subcommands inherit it)
        return super().init_parser(**kwargs)

    def add_arguments_to_parser(self, parser: LightningArgumentParser) -> None:
        # the data section's clip options are the one place these numbers are written
        for name in ("num_frames", "image_size", "crop_top"):
            parser.link_arguments(f"data.clip.{name}", f"model.{name}")
        parser.add_lightning_class_args(LaneEvalCallback, "eval")
        parser.add_lightning_class_args(LanePredictionWriter, "predictions")
        parser.add_argument(
            "--source",
            type=str | None,
            default=None,
            help="predict only: a folder of frames or a video file to predict on instead of the data split",
        )

    def parse_arguments(self, parser: LightningArgumentParser, args: Any) -> None:
        given = list(args) if isinstance(args, (list, tuple)) else sys.argv[1:] if args is None else []
        check_flags(given)  # --data.num_frames: one line naming --data.clip.num_frames
        try:
            super().parse_arguments(parser, args)
        except ArgumentError as err:  # a refused class: the key and the class, not 400 characters of type hints
            raise ArgumentError(None, refused_class(str(err)) or str(err)) from None
        # the config's paths (data.root, model.init_weights, ...) through the gate of the flags' paths, whichever
        # file named them: a name too long, a NUL byte, a FIFO or a loop of links is one line, never opened
        check_config_paths(self._command_config())
        self._check_option_groups()
        logs_under_root(self._command_config().get("trainer"))  # a RunLogger without a save_dir: the trainer's root
        self._logs_outside_run()

    def _command_config(self) -> Namespace:
        """The parsed options of the subcommand (the whole config when there is none: ``run=False``)."""
        config: Namespace = self.config.get(str(self.config.get("subcommand"))) or self.config
        return config

    def _check_option_groups(self) -> None:
        """An option group (a dataclass such as ``data.loader`` or ``model.postprocess``) given as anything but a
        mapping (``data.loader: [1, 2]``) passes jsonargparse's parsing and fails when it is built, as a
        TypeError without the key: said here, in one line naming it (ValueError)."""
        config = self._command_config()
        for section, cls in (("model", StamLaneModule), ("data", ClipDataModule)):
            for name, hint in typing.get_type_hints(cls.__init__).items():
                arms = typing.get_args(hint) or (hint,)
                if not any(dataclasses.is_dataclass(arm) for arm in arms):
                    continue
                value = config.get(f"{section}.{name}")
                if value is not None and not isinstance(value, Namespace):
                    raise ValueError(f"{section}.{name} must be a mapping of options, got {value!r:.80}")

    def _logs_outside_run(self) -> None:
        """Keep ``validate``, ``test`` and ``predict`` out of a training run's log folder (``save_dir/name``, where
        each would add a ``version_N``): ``predict`` logs nothing (Lightning's predict loop logs no metric: its
        output is ``predictions.output_dir``), ``validate`` and ``test`` log their metrics under
        ``save_dir/<name>-validate`` / ``<name>-test`` (`stamlane.training.stored_cli.scoring_name`)."""
        from stamlane.training.stored_cli import RENAMED_LOGGERS, scoring_name

        subcommand = str(self.config.get("subcommand"))
        trainer = self.config[subcommand].get("trainer") if subcommand in ("validate", "test", "predict") else None
        if trainer is None or not trainer.get("logger"):
            return
        if subcommand == "predict":
            trainer["logger"] = False
            return
        for one in each_logger(trainer["logger"]):
            init = getattr(one, "init_args", None)
            if init is not None and str(getattr(one, "class_path", "")).endswith(RENAMED_LOGGERS):
                init["name"] = scoring_name(init.get("name"), subcommand)

    # the command line stays in charge of the model's settings (see stamlane.training.lightning_compat)
    _parse_ckpt_path = keep_command_line_hparams

    def instantiate_trainer(self, **kwargs: Any) -> Trainer:
        logged = self.subcommand is not None and self.config[self.subcommand]["trainer"].get("logger") not in (
            None,
            False,
        )
        if self.subcommand == "predict" or (self.subcommand != "fit" and not logged):
            # predict's files go to its output folder, and a validate or test without a logger has no log folder:
            # no config.yaml in the folder it is run from
            self.save_config_callback = None
        trainer = super().instantiate_trainer(**kwargs)
        callbacks_of(trainer).insert(0, ExactResume())  # --ckpt_path resume draws the data of an uninterrupted run
        callbacks_of(trainer).append(FinalCheckpoint())  # last.ckpt = the weights training ended with
        if self.subcommand == "fit":  # the run's config travels inside its checkpoints (predict from one alone)
            config = subcommand_parser(self, self.subcommand).dump(self.config[self.subcommand], skip_none=False)
            callbacks_of(trainer).append(ConfigInCheckpoint(config))
            callbacks_of(trainer).append(FitReport(verbose=self.report))  # a line per validation, the true best
        elif self.subcommand is not None:  # checkpoints and learning rates are fit's: nothing to save or restore
            callbacks_of(trainer)[:] = [
                cb for cb in callbacks_of(trainer) if not isinstance(cb, (ModelCheckpoint, LearningRateMonitor))
            ]
        return trainer

    def before_fit(self) -> None:
        self._check("fit")

    def after_fit(self) -> None:
        """Say where the model went and how good it is: best validation F1 and its step, checkpoints, logs."""
        if self.trainer.global_rank != 0 or not self.report:
            return
        if spawned(self.trainer):  # this process only started the ranks; the run's record is theirs
            where = self.trainer.logger.log_dir if self.trainer.logger is not None else self.trainer.default_root_dir
            print(f"stamlane fit: done ({self.trainer.world_size} processes); checkpoints, logs and config: {where}")
            return
        lines = [f"stamlane fit: done after {self.trainer.global_step} steps"]
        report = next((cb for cb in callbacks_of(self.trainer) if isinstance(cb, FitReport)), None)
        keeper = next(
            (cb for cb in self.trainer.checkpoint_callbacks if isinstance(cb, ModelCheckpoint) and cb.monitor), None
        )
        best = report.best_checkpoint(self.trainer) if report is not None else None
        if keeper is not None and best is not None:  # the run resumed from included
            step = best.step if best.step is not None else step_of(best.path)
            where = f": {best.path}" if best.path else ""
            lines.append(f"  best {keeper.monitor} {best.score:.4f}{f' at step {step}' if step else ''}{where}")
        last = next(
            (
                cb.last_model_path
                for cb in self.trainer.checkpoint_callbacks
                if isinstance(cb, ModelCheckpoint) and cb.last_model_path
            ),
            None,
        )
        if last:
            lines.append(f"  last (final weights): {last}")
        if self.trainer.logger is not None and self.trainer.logger.log_dir:
            lines.append(f"  logs and config: {self.trainer.logger.log_dir}")
        print("\n".join(lines), flush=True)

    def before_validate(self) -> None:
        self._check("validate")

    def before_test(self) -> None:
        self._check("test")

    def after_validate(self) -> None:
        self._say_logs("validate")

    def after_test(self) -> None:
        self._say_logs("test")

    def _say_logs(self, subcommand: str) -> None:
        logger = self.trainer.logger
        if self.report and self.trainer.is_global_zero and logger is not None and logger.log_dir:
            print(f"stamlane {subcommand}: metrics logged under {logger.log_dir}", flush=True)

    def _check(self, subcommand: str) -> None:
        if self.config[subcommand].get("source"):
            raise SystemExit(f"stamlane {subcommand}: --source is for predict only")
        self._check_outputs(subcommand)
        self._safe_load(subcommand)

    def _check_outputs(self, subcommand: str) -> None:
        """No output (``--trainer.default_root_dir``, a logger's ``save_dir``, ``--predictions.output_dir``, the
        merged ``config.yaml`` the run writes, ``predictions.json``) may be an input or lie inside one (the data
        root, ``--source``, a ``--config`` file), nor replace a file the command reads (the checkpoint), symlinks
        resolved: logs, checkpoints and predictions never land among the frames and labels they are made from
        (`stamlane.safety.guard.check_outputs`).

        Raises:
            GuardError: naming the output and the input.
        """
        config = self.config[subcommand]
        configs = [str(c) for c in config.get("config") or []]
        inputs = [getattr(self.datamodule, "root", None), config.get("source"), *configs]
        ckpt = self.config_init[subcommand].get("ckpt_path") if subcommand != "fit" else None
        reads = [*inputs, ckpt if ckpt not in ("last", "best", "hpc", "registry") else None]
        folders: list[str | Path | None] = [self.trainer.default_root_dir]
        folders += [lg.save_dir for lg in self.trainer.loggers if getattr(lg, "save_dir", None)]
        folders += [getattr(cb, "dirpath", None) for cb in self.trainer.checkpoint_callbacks]  # a ModelCheckpoint's
        files: list[str | Path | None] = []
        saver = next((cb for cb in callbacks_of(self.trainer) if isinstance(cb, SaveConfigCallback)), None)
        if saver is not None:  # the merged config, written over a --config of the same name in that folder
            files.append(Path(self.trainer.log_dir or self.trainer.default_root_dir) / saver.config_filename)
        if subcommand == "predict":
            for cb in callbacks_of(self.trainer):
                if isinstance(cb, LanePredictionWriter):
                    folders += [cb.output_dir, cb.output_dir / "lines", cb.output_dir / "overlays"]
                    files += [cb.output_dir / "predictions.json", cb.video_path, temporary_name(cb.video_path)]
        check_outputs(files, reads, folders=folders, protected=inputs)

    def _safe_load(self, subcommand: str) -> None:
        # our checkpoints hold only tensors and plain values, so they load with weights_only=True (Lightning
        # would default to False); a foreign, trusted checkpoint may need --weights_only false
        if self.config_init[subcommand].get("weights_only") is None:
            self.config_init[subcommand]["weights_only"] = True
        path = self.config_init[subcommand].get("ckpt_path")
        if path == "last":  # Lightning looks only where THIS run would save, and silently starts from step 0
            path = self.config_init[subcommand]["ckpt_path"] = str(self._last_checkpoint())
        if path is not None and path not in ("best", "hpc", "registry"):
            # a missing, truncated or foreign file, or weights of another network: one line, not a traceback
            self._check_fits(path, read_checkpoint(path))

    def _check_fits(self, path: str, content: dict[str, Any]) -> None:
        """Refuse, before Lightning restores it (a KeyError or a RuntimeError of many lines there), a checkpoint
        without Lightning's version record or whose weights do not fit the network the config builds.

        Raises:
            CheckpointError: naming the file, the count of missing / unexpected / reshaped weights and the first.
        """
        if "pytorch-lightning_version" not in content:
            raise CheckpointError(f"checkpoint {path} records no pytorch-lightning_version (not written by Lightning)")
        own, stored = self.model.state_dict(), content["state_dict"]
        problems = {
            "missing": [k for k in own if k not in stored],
            "unexpected": [k for k in stored if k not in own],
            "of another shape": [k for k in own if k in stored and getattr(stored[k], "shape", None) != own[k].shape],
        }
        said = [f"{len(keys)} weights {what} (first: {keys[0]})" for what, keys in problems.items() if keys]
        if said:
            raise CheckpointError(f"checkpoint {path} does not fit the network of the config: {'; '.join(said)}")

    def _last_checkpoint(self) -> Path:
        """The newest ``last.ckpt`` under the run's logger folder (``save_dir/name``), else ``default_root_dir``."""
        logger = self.trainer.logger
        folder = Path(self.trainer.default_root_dir)
        save_dir = logger.save_dir if logger is not None else None
        if logger is not None and save_dir:
            folder = Path(save_dir) / (logger.name or "")
        found = sorted(folder.rglob("last*.ckpt"), key=lambda p: p.stat().st_mtime) if folder.is_dir() else []
        if not found:
            raise CheckpointError(
                f"--ckpt_path last: no last.ckpt under {folder} (nothing to resume): leave --ckpt_path out to start "
                f"the run, or give a checkpoint's path"
            )
        return found[-1]

    def before_predict(self) -> None:
        source = self.config["predict"].get("source")
        if source:
            # read as the model was trained; a folder has no alignment cache nor true homographies: ORB on the fly
            data = self.datamodule
            clip = data.clip if data.clip.align in ("fly", "none") else replace(data.clip, align="fly", cache_dir=None)
            self.datamodule = FramesDataModule(source, clip, data.loader, history_source=data.history_source)
        self._name_predictions(source)
        self._check_outputs("predict")  # before the checkpoint is read: an output named like it is refused first
        self._safe_load("predict")
        if source:  # a video decoded now; frames that are no sequence said in one line
            warn_sequence(self.datamodule, say=self.trainer.is_global_zero)

    def _name_predictions(self, source: str | None) -> None:
        """The prediction writer's folder and legend name (`stamlane.training.stored_predict.name_predictions`: one
        folder per model, the checkpoint's run, and source)."""
        ckpt = self.config_init["predict"].get("ckpt_path")
        configs = [str(c) for c in self.config["predict"].get("config") or []]
        for writer in callbacks_of(self.trainer):
            if isinstance(writer, LanePredictionWriter):
                name_predictions(writer, self.datamodule, source, checkpoint_name(ckpt, configs))


def checkpoint_name(ckpt: str | None, configs: list[str]) -> str:
    """The name of a model for its prediction folder and legends: the run a checkpoint belongs to
    (``outputs/demo/stam4-s0/run/checkpoints/last.ckpt`` -> ``stam4-s0``, ``runs/stam4/version_3/checkpoints/
    last.ckpt`` -> ``stam4-version_3``), with the checkpoint's name unless it is ``last`` (``...-best-step=400``);
    a checkpoint outside a run folder by its file name; without one, the config's name and ``-untrained``."""
    if not ckpt:
        return f"{Path(configs[-1]).stem}-untrained" if configs else "untrained"
    path = Path(ckpt)
    if path.parent.name != "checkpoints":
        return path.stem
    run = path.parent.parent
    name = run.parent.name if run.name == "run" else run.name
    if re.fullmatch(r"version_\d+", run.name):
        name = f"{run.parent.name}-{run.name}"
    return name if path.stem == "last" else f"{name}-{path.stem}"
