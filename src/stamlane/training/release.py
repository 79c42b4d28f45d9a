"""A trained run's checkpoint made into weights to ship: ``python -m stamlane.training.release CKPT OUT``.

What a run's ``last.ckpt`` holds beyond the model (optimiser and scheduler state, the resume loops, the callbacks'
state, the folder the run was started in) is dropped; the run's config and hyper_parameters are kept in today's
names (`stamlane.training.compat`), checked by the closed registry, with what names the training machine cleared:
the data root (the default synthetic set), the weights the run started from, the output folders, the logger and
the callbacks (``predict`` / ``validate`` / ``test`` do not use them). The trainer's accelerator becomes ``auto``,
so that the weights run on a GPU where there is one. The model's weights are the run's, bit for bit. The shipped
models (`stamlane.weights`) were made so (docs/models.md).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

__all__ = ["KEPT", "main", "release"]

KEPT = (
    "epoch",
    "global_step",
    "pytorch-lightning_version",
    "state_dict",
    "hparams_name",
    "hyper_parameters",
    "datamodule_hparams_name",
    "datamodule_hyper_parameters",
)
"""The keys of a Lightning checkpoint a released one keeps, besides the run config (`CONFIG_KEY`)."""


def _cleared_config(config: dict[str, Any]) -> dict[str, Any]:
    config = dict(config)
    trainer = {k: v for k, v in (config.get("trainer") or {}).items() if k not in ("default_root_dir", "callbacks")}
    config["trainer"] = trainer | {"accelerator": "auto", "logger": False}
    config["data"] = dict(config.get("data") or {}) | {"root": None}
    config["model"] = dict(config.get("model") or {}) | {"init_weights": None}
    if isinstance(config.get("predictions"), dict):
        config["predictions"] = {k: v for k, v in config["predictions"].items() if k != "output_dir"}
    config.pop("ckpt_path", None)
    return config


def release(ckpt: Path, out: Path) -> dict[str, Any]:
    """Write ``ckpt`` (a run's checkpoint) to ``out`` as weights to ship; returns what was written.

    Raises:
        CheckpointError: ``ckpt`` is not a checkpoint stamlane reads (see `stamlane.safety.checkpoints`), or its
            config or hyper_parameters are refused by the registry.
    """
    import torch
    import yaml

    from stamlane.safety.checkpoints import CheckpointError, read_checkpoint
    from stamlane.safety.guard import atomic_path, check_outputs
    from stamlane.training.lightning_cli import CONFIG_KEY
    from stamlane.training.registry import check_data_hparams, check_hparams, check_run_config

    check_outputs([out], [ckpt], protected=[ckpt])
    content = read_checkpoint(ckpt)
    if not isinstance(content.get(CONFIG_KEY), str):
        raise CheckpointError(f"checkpoint {ckpt} carries no run config: only a checkpoint of `stamlane fit` ships")
    config = _cleared_config(check_run_config(content[CONFIG_KEY], ckpt))
    released = {key: content[key] for key in KEPT if key in content}
    released["hyper_parameters"] = check_hparams(content["hyper_parameters"], ckpt) | {"init_weights": None}
    if "datamodule_hyper_parameters" in content:
        check_data_hparams(content["datamodule_hyper_parameters"], ckpt)
        released["datamodule_hyper_parameters"] = dict(content["datamodule_hyper_parameters"]) | {"root": None}
    released[CONFIG_KEY] = yaml.safe_dump(config, sort_keys=False)
    check_run_config(released[CONFIG_KEY], out)  # what ships is what the registry reads back
    with atomic_path(out) as tmp:  # makes the folder (one line when it cannot)
        torch.save(released, tmp)
    return released


def main(argv: list[str] | None = None) -> int:
    from stamlane.safety.boundary import run_command
    from stamlane.safety.checkpoints import CheckpointError
    from stamlane.safety.paths import check_arguments

    parser = argparse.ArgumentParser(prog="python -m stamlane.training.release", description=__doc__.split("\n")[0])
    parser.add_argument("ckpt", type=Path, help="a run's checkpoint (RUN/checkpoints/last.ckpt)")
    parser.add_argument("out", type=Path, help="the file to write")
    args = parser.parse_args(argv)

    def body() -> int:
        check_arguments(sys.argv[1:] if argv is None else argv)  # the path gate's door (`stamlane.safety.paths`)
        release(args.ckpt, args.out)
        return 0

    return run_command("release", body, CheckpointError)


if __name__ == "__main__":
    sys.exit(main())
