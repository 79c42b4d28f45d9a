"""A stored model's predictions of a data module: a plain ``lightning.Trainer.predict``.

`predict_stored` is the one way a `stamlane.training.stored.StoredModel` predicts a split, a folder of frames or a
video into files: a ``Trainer`` made for prediction alone (no logger, no checkpoints, one process unless asked), the
model as it was opened (the checkpoint is not read again) and the lane writer
(`stamlane.predict.prediction_writer.LanePredictionWriter`). ``stamlane predict --ckpt_path``
(`stamlane.training.stored_cli`), `stamlane.training.runs.Run.predict` and, through it, the experiment runner's
scores go through it. The same three steps before the writer writes are shared with ``stamlane predict --config``
(`stamlane.training.lightning_cli.StamLaneCLI`): `name_predictions` (the output folder per model and source, claimed),
`check_prediction_outputs` (no output among the inputs) and `warn_sequence` (a source that is no sequence).
"""

from __future__ import annotations

import sys
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from stamlane.predict.prediction_writer import LanePredictionWriter
    from stamlane.training.stored import StoredModel

__all__ = [
    "PREDICT_TRAINER_OPTIONS",
    "check_prediction_outputs",
    "name_predictions",
    "predict_stored",
    "prediction_trainer_options",
    "seed_run",
    "warn_sequence",
]

PREDICT_TRAINER_OPTIONS = (
    "accelerator",
    "precision",
    "deterministic",
    "benchmark",
    "inference_mode",
    "limit_predict_batches",
    "enable_progress_bar",
)
"""The options of a run's stored trainer that its predictions keep (where and how the network runs); the rest
(steps, validation, logger, checkpoints, processes) are training's."""


def prediction_trainer_options(
    trainer: Mapping[str, Any], keep: Sequence[str] | None = PREDICT_TRAINER_OPTIONS
) -> dict[str, Any]:
    """The ``lightning.Trainer`` options of a prediction (or, ``keep`` None, a validation or test) of a run whose
    trainer section is ``trainer``: its options named in ``keep`` (None: all) that are set, in one process
    (``devices: 1``, ``num_nodes: 1``, ``strategy: auto``: a run trained on 8 GPUs is scored in one), except under a
    launcher that starts the processes itself (``torchrun``, SLURM's ``srun``:
    `stamlane.training.launch.launched_by_cluster`), where its own are kept."""
    from stamlane.training.launch import launched_by_cluster

    options = {k: v for k, v in trainer.items() if (keep is None or k in keep) and v is not None}
    if launched_by_cluster():
        return options | {k: trainer[k] for k in ("devices", "num_nodes", "strategy") if trainer.get(k) is not None}
    return options | {"devices": 1, "num_nodes": 1, "strategy": "auto"}


def seed_run(seed: int | bool | None) -> None:
    """``lightning.seed_everything`` as LightningCLI does for ``--seed_everything``: an int seeds with it, True with
    a drawn seed, None or False not at all (the workers seeded too, quietly)."""
    from lightning.pytorch import seed_everything

    if seed is not None and seed is not False:
        seed_everything(None if seed is True else int(seed), workers=True, verbose=False)


def predict_stored(
    model: StoredModel,
    data: Any,
    writer: LanePredictionWriter,
    *,
    seed: int | bool | None = None,
    callbacks: Sequence[Any] = (),
    **trainer: Any,
) -> LanePredictionWriter:
    """Predict ``data`` with ``model`` into ``writer``'s folder: ``lightning.Trainer(**trainer).predict``.

    Args:
        model: the stored model (its module is used as it is: the weights are not loaded again).
        data: the LightningDataModule to predict (its ``predict_dataloader``).
        writer: the lane writer, already given its folder (`name_predictions`).
        seed: ``lightning.seed_everything`` first, as ``stamlane predict`` has always done (None or False: not).
        callbacks: Lightning callbacks besides the writer.
        **trainer: ``lightning.Trainer`` options (`prediction_trainer_options` of the run's trainer, then the
            caller's); no checkpoints, and no logger unless one is given.

    Returns:
        ``writer``, holding what it wrote (``written``).
    """
    from lightning.pytorch import Trainer

    seed_run(seed)
    options = {"enable_model_summary": False, "logger": False, **trainer}
    runner = Trainer(callbacks=[*callbacks, writer], enable_checkpointing=False, **options)
    runner.predict(model.module, datamodule=data, return_predictions=False)
    return writer


def name_predictions(writer: LanePredictionWriter, data: Any, source: str | None, model: str) -> None:
    """Give ``writer`` its folder when none was given, ``outputs/predict/<model>/<source>``
    (`stamlane.predict.prediction_writer.default_output_dir`: the source's name, or the data root and split), claimed
    for this source (`stamlane.safety.owner.claim`: a second source of the same name gets its own folder; a folder
    given that holds another source's results is refused), and the name its legends show when none was given.

    Args:
        writer: the lane writer.
        data: the data module (its ``root`` and ``split_labels("predict")``; not read when ``source`` is given).
        source: the folder of frames or the video predicted, or None (a split of ``data``).
        model: the model's name (`stamlane.training.lightning_cli.checkpoint_name`).

    Raises:
        GuardError: a given folder that holds another source's results.
    """
    from stamlane.predict.prediction_writer import default_output_dir
    from stamlane.safety.owner import claim

    if source:
        path = Path(source).resolve()
        what, origin = (path.stem if path.is_file() else path.name), str(path)
    else:
        labels = "+".join(Path(f).stem for f in data.split_labels("predict"))
        what = f"{Path(data.root).resolve().name}-{labels}"
        origin = f"{Path(data.root).resolve()}: {labels}"
    owner = {"command": "predict", "source": origin}
    if writer.given_output_dir:
        claim(writer.output_dir, owner, "--predictions.output_dir")
    else:
        writer.use_output_dir(claim(default_output_dir(model, what), owner, "--predictions.output_dir", chosen=True))
    writer.owner = owner
    if writer.model_name is None:
        writer.model_name = model


def check_prediction_outputs(
    writer: LanePredictionWriter,
    inputs: Sequence[str | Path | None],
    reads: Sequence[str | Path | None] = (),
    folders: Sequence[str | Path | None] = (),
    files: Sequence[str | Path | None] = (),
) -> None:
    """No file of ``writer`` (its folder, ``lines/``, ``overlays/``, ``predictions.json``, the overlay video and its
    temporary name), nor ``folders`` / ``files`` (a trainer's), may be an input or lie inside one (``inputs``: the
    data root, the source, a config), nor replace a file read (``reads``: the checkpoint)
    (`stamlane.safety.guard.check_outputs`).

    Raises:
        GuardError: naming the output and the input.
    """
    from stamlane.safety.guard import check_outputs, temporary_name

    out = writer.output_dir
    check_outputs(
        [*files, out / "predictions.json", writer.video_path, temporary_name(writer.video_path)],
        [*inputs, *reads],
        folders=[*folders, out, out / "lines", out / "overlays"],
        protected=inputs,
    )


def warn_sequence(data: Any, say: bool) -> None:
    """Read a source now (``prepare_data`` and ``setup``: a video is decoded) and say in one line, on stderr (where
    ``say``: the first process), when its frames are not one sequence and the history is used anyway
    (`stamlane.data.datamodule.SequenceWarning`); any other warning is shown as it would have been."""
    from stamlane.data.datamodule import SequenceWarning

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", SequenceWarning)
        data.prepare_data()
        data.setup("predict")
    for warning in caught:
        if issubclass(warning.category, SequenceWarning):
            if say:
                print(f"stamlane predict: warning: {warning.message}", file=sys.stderr, flush=True)
        else:
            warnings.showwarning(warning.message, warning.category, warning.filename, warning.lineno)
