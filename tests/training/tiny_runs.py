"""The tiny run of the training tests: the demo config shrunk to seconds."""

from __future__ import annotations

from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def tiny_args(root: Path, out: Path, *extra: str) -> list[str]:
    """The demo config shrunk: 2 frames at 32x64, width 1/16, float32, 2 clips a batch (2 steps an epoch), no
    checkpoint callbacks but ``last.ckpt`` (`stamlane.training.final_checkpoint`)."""
    return [
        "--config",
        str(REPO / "configs" / "demo.yaml"),
        f"--data.root={root}",
        "--data.clip.num_frames=2",
        "--data.clip.image_size=[32,64]",
        "--data.loader.batch_size=2",
        "--data.loader.num_workers=0",
        "--data.clip.align=none",
        "--model.encoder.width=0.0625",
        "--model.bf16=false",
        "--model.channels_last=false",
        f"--trainer.default_root_dir={out}",
        f"--trainer.logger.save_dir={out}",
        "--trainer.enable_progress_bar=false",
        "--trainer.enable_model_summary=false",
        "--trainer.callbacks=[]",
        "--trainer.callbacks+=lightning.pytorch.callbacks.ModelCheckpoint",
        "--trainer.callbacks.monitor=null",
        "--trainer.callbacks.save_last=true",
        f"--predictions.output_dir={out / 'predictions'}",
        *extra,
    ]
