"""The tiny run of the training tests: the demo config shrunk to seconds."""

from __future__ import annotations

from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def shrunk_demo_args(root: Path, out: Path, *extra: str, size: str, width: float, align: str = "none") -> list[str]:
    """The demo config shrunk for a test run: 2 frames of ``size``, encoder ``width``, float32, contiguous tensors,
    2 clips a batch (2 steps an epoch on 4 clips), no progress bar or summary, every output under ``out``.

    Args:
        root: the data root (a TuSimple-layout set).
        out: the folder of the run (logs, checkpoints, predictions).
        *extra: more arguments, after these (they win).
        size: ``--data.clip.image_size``, e.g. ``"[32,64]"``.
        width: ``--model.encoder.width``.
        align: ``--data.clip.align``.
    """
    return [
        "--config",
        str(REPO / "configs" / "demo.yaml"),
        f"--data.root={root}",
        "--data.clip.num_frames=2",
        f"--data.clip.image_size={size}",
        "--data.loader.batch_size=2",
        "--data.loader.num_workers=0",
        f"--data.clip.align={align}",
        f"--model.encoder.width={width}",
        "--model.bf16=false",
        "--model.channels_last=false",
        f"--trainer.default_root_dir={out}",
        f"--trainer.logger.save_dir={out}",
        "--trainer.enable_progress_bar=false",
        "--trainer.enable_model_summary=false",
        f"--predictions.output_dir={out / 'predictions'}",
        *extra,
    ]


def tiny_args(root: Path, out: Path, *extra: str) -> list[str]:
    """The demo config shrunk: 2 frames at 32x64, width 1/16, float32, 2 clips a batch (2 steps an epoch), no
    checkpoint callbacks but ``last.ckpt`` (`stamlane.training.final_checkpoint`)."""
    return shrunk_demo_args(
        root,
        out,
        "--trainer.callbacks=[]",
        "--trainer.callbacks+=lightning.pytorch.callbacks.ModelCheckpoint",
        "--trainer.callbacks.monitor=null",
        "--trainer.callbacks.save_last=true",
        *extra,
        size="[32,64]",
        width=0.0625,
    )
