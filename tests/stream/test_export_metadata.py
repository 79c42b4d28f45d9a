"""``stamlane export``: the .onnx carries its preprocessing, clip layout and decoding settings, read from the
checkpoint; without the ``export`` extra, one line with the install command and exit status 2."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import subprocess
import sys
from importlib.metadata import version
from pathlib import Path

import pytest
import torch

from stamlane.cli import main as stamlane
from stamlane.predict.postprocess import PostprocessConfig
from stamlane.stream.metadata import METADATA_KEYS, read_metadata

from .conftest import CLIP, POSTPROCESS

torch.set_num_threads(1)
onnx = pytest.importorskip("onnx", reason="onnx is not installed")
ort = pytest.importorskip("onnxruntime", reason="onnxruntime is not installed")


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory, save_checkpoint) -> tuple[Path, Path, Path]:
    """(checkpoint, clip.onnx, streaming folder) of one `stamlane export --streaming` run."""
    folder = tmp_path_factory.mktemp("export")
    ckpt = save_checkpoint(folder / "last.ckpt")
    assert (
        stamlane(
            ["export", "--ckpt_path", str(ckpt), "--output", str(folder / "m.onnx"), "--streaming", str(folder / "s")]
        )
        == 0
    )
    return ckpt, folder / "m.onnx", folder / "s"


def test_the_onnx_carries_the_checkpoints_preprocessing_and_decoding(exported: tuple[Path, Path, Path]) -> None:
    from stamlane.training.module import StamLaneModule

    ckpt, path, _ = exported
    module = StamLaneModule.from_checkpoint(ckpt)
    meta = read_metadata(path)
    assert tuple(meta) == METADATA_KEYS
    assert meta["format"] == "stamlane-onnx/1" and meta["graph"] == "clip"
    assert meta["stamlane_version"] == version("stamlane")
    assert meta["checkpoint"] == "last.ckpt"
    assert meta["checkpoint_sha256"] == hashlib.sha256(ckpt.read_bytes()).hexdigest()
    # the clip layout and the preprocessing, as the module records them
    assert meta["num_frames"] == module.num_frames == 3 and meta["key_frame"] == "last"
    assert meta["image_size"] == list(module.hparams["image_size"]) == [64, 128]
    assert meta["crop_top"] == module.crop_top == 0.25
    assert meta["colour_order"] == "RGB" and meta["value_range"] == [0.0, 1.0] and "/ 255" in meta["normalisation"]
    assert meta["input_layout"].startswith("B, T, 3, H, W")
    assert meta["alignment"] == {
        "history": "pre-aligned",
        "by": meta["alignment"]["by"],
        "source": "fly",
        "warp": "image",
        "strategy": "chain",
        "preset": "standard",
        "horizon_row": 40,
    }
    assert "ORB" in meta["alignment"]["by"]
    # decoding: every field of the module's PostprocessConfig (JSON: its tuples as lists), the ones the config set
    # among them; the metadata alone rebuilds the module's decoding
    assert meta["postprocess"] == json.loads(json.dumps(dataclasses.asdict(module.postprocess)))
    assert PostprocessConfig(**meta["postprocess"]) == module.postprocess
    assert all(meta["postprocess"][k] == v for k, v in POSTPROCESS.items())
    assert meta["lane_channel"] == 1 and meta["precision"] == "float32"
    # inputs and outputs: what onnxruntime sees in the graph
    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    assert meta["input_names"] == [i.name for i in session.get_inputs()] == ["clip"]
    assert meta["output_names"] == [o.name for o in session.get_outputs()] == ["logits", "embedding"]
    assert meta["input_shapes"] == {"clip": ["batch", 3, 3, 64, 128]}
    assert meta["output_shapes"] == {"logits": ["batch", 2, 64, 128], "embedding": ["batch", 3, 64, 128]}
    model = onnx.load(str(path))
    assert meta["opset"] == max(o.version for o in model.opset_import if o.domain in ("", "ai.onnx")) == 17
    # onnxruntime hands the same metadata to a reader without the onnx package
    plain = {k: json.loads(v) for k, v in session.get_modelmeta().custom_metadata_map.items()}
    assert plain == meta


def test_the_streaming_graphs_carry_it_too(exported: tuple[Path, Path, Path]) -> None:
    _, path, folder = exported
    clip_meta = read_metadata(path)
    for graph in ("encoder", "fuse_decode"):
        meta = read_metadata(folder / f"{graph}.onnx")
        assert meta["graph"] == graph
        assert {k: v for k, v in meta.items() if not k.startswith(("graph", "input", "output"))} == {
            k: v for k, v in clip_meta.items() if not k.startswith(("graph", "input", "output"))
        }
    assert read_metadata(folder / "encoder.onnx")["input_names"] == ["frames"]
    assert read_metadata(folder / "fuse_decode.onnx")["input_names"][:2] == ["history", "grid"]
    assert not list(folder.parent.rglob(".*tmp*"))  # every graph written whole, then renamed


@pytest.mark.parametrize(
    ("clip", "alignment"),
    [
        (CLIP | {"align": "none", "warp": "image"}, {"history": "unaligned", "source": "none"}),
        (CLIP | {"align": "true", "align_strategy": "direct"}, {"history": "pre-aligned", "strategy": "direct"}),
        (CLIP | {"align": "fly", "warp": "feature"}, {"history": "pre-aligned", "warp": "feature"}),
        (None, None),
    ],
)
def test_the_alignment_is_the_runs_or_null(
    tmp_path: Path, save_checkpoint, clip: dict | None, alignment: dict | None
) -> None:
    ckpt = save_checkpoint(tmp_path / "c.ckpt", clip=clip)
    assert stamlane(["export", "--ckpt_path", str(ckpt)]) == 0
    meta = read_metadata(tmp_path / "c.onnx")
    if alignment is None:  # no data options in the checkpoint: not guessed
        assert meta["alignment"] is None and meta["crop_top"] == 0.25  # the module's own
    else:
        assert {k: meta["alignment"][k] for k in alignment} == alignment


def test_the_parity_line_names_float32(exported: tuple[Path, Path, Path], tmp_path: Path, capsys) -> None:
    ckpt, _, _ = exported
    assert stamlane(["export", "--ckpt_path", str(ckpt), "--output", str(tmp_path / "p.onnx")]) == 0
    said = capsys.readouterr().out
    assert "parity with PyTorch, float32 both" in said
    assert float(said.split("max |logits| diff ")[1].split(",")[0]) < 1e-4


@pytest.mark.parametrize("package", ["onnx", "onnxscript", "onnxruntime"])
def test_without_the_export_extra_one_line_and_status_2(exported, tmp_path: Path, package: str) -> None:
    """Checked in a fresh interpreter with the package blocked: the install command, nothing written, and torch
    not even imported (the answer comes at once)."""
    ckpt, _, _ = exported
    out = tmp_path / "m.onnx"
    code = (
        f"import sys; sys.modules[{package!r}] = None\n"
        "from stamlane.cli import main\n"
        f"status = main(['export', '--ckpt_path', {str(ckpt)!r}, '--output', {str(out)!r}])\n"
        "print(status, 'torch' in sys.modules)\n"
    )
    env = os.environ | {"OMP_WAIT_POLICY": "PASSIVE"}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, env=env)
    assert done.stdout.split() == ["2", "False"], done
    assert done.stderr.strip().splitlines() == [
        f'stamlane export: exporting to ONNX needs {package} (the export extra): pip install "stamlane[export]"'
    ]
    assert not out.exists() and list(tmp_path.iterdir()) == []
