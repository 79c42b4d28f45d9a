"""The onnxruntime example of docs/streaming.md runs as it is written, and feeds the graph what stamlane feeds the
network: the same clip, so the same logits (the doc cannot rot)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import torch

from stamlane.cli import main as stamlane
from stamlane.synth import SynthConfig, generate_dataset
from stamlane.synth.layout import SplitCounts

torch.set_num_threads(1)
pytest.importorskip("onnx", reason="onnx is not installed")
pytest.importorskip("onnxruntime", reason="onnxruntime is not installed")

DOC = Path(__file__).resolve().parents[2] / "docs" / "streaming.md"
MARKER = "<!-- tested: the block below runs in tests/stream/test_onnx_example.py -->"


def doc_example() -> str:
    """The python block right after `MARKER` in docs/streaming.md."""
    text = DOC.read_text()
    assert text.count(MARKER) == 1, f"{DOC} must hold the marker once"
    match = re.match(r"\s*```python\n(.*?)\n```", text[text.index(MARKER) + len(MARKER) :], re.DOTALL)
    assert match, f"no python block right after the marker in {DOC}"
    return match.group(1)


@pytest.fixture(scope="module", params=[(160, 96), (320, 192)], ids=["resized", "area-averaged-first"])
def workdir(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory, save_checkpoint) -> Path:
    """What the example reads: ``stam4.onnx`` exported from a tiny checkpoint (64x128 input, the top quarter cut)
    and ``data/synth``, a synthetic set of one 20-frame test clip: at 160x96 the frames are only resized, at 320x192
    they shrink below 0.6 and are area-averaged first."""
    folder = tmp_path_factory.mktemp("example")
    width, height = request.param
    config = SynthConfig(width=width, height=height, num_frames=20)
    generate_dataset(folder / "data/synth", SplitCounts(test=1), config=config, progress=False)
    ckpt = save_checkpoint(folder / "last.ckpt")
    assert stamlane(["export", "--ckpt_path", str(ckpt), "--output", str(folder / "stam4.onnx")]) == 0
    return folder


def test_the_example_runs_and_feeds_what_stamlane_feeds(workdir: Path, monkeypatch, capsys) -> None:
    from stamlane.align import estimate_clip
    from stamlane.data.transforms import ClipTransform
    from stamlane.training.module import StamLaneModule

    monkeypatch.chdir(workdir)
    namespace: dict = {}
    exec(compile(doc_example(), str(DOC), "exec"), namespace)
    assert "lanes; the first points of each" in capsys.readouterr().out
    lanes = namespace["lanes"]
    assert isinstance(lanes, list) and all(lane.ndim == 2 and lane.shape[1] == 2 for lane in lanes)
    height, width = namespace["frames"][-1].shape[:2]
    for lane in lanes:  # in frame pixels, below the rows the network never saw
        assert (lane[:, 0] >= 0).all() and (lane[:, 0] <= width - 1).all() and (lane[:, 1] >= height / 4).all()
    assert (namespace["scale"] < 0.6) == (width == 320)  # both branches of the resize are run

    # stamlane's own path on the same frames: its alignment settings, ClipTransform, the PyTorch network
    module = StamLaneModule.from_checkpoint(workdir / "last.ckpt")
    frames = namespace["frames"]
    transform = ClipTransform(tuple(module.hparams["image_size"]), crop_top=module.crop_top)
    params = transform.draw(frames[-1].shape[:2])
    assert np.allclose(namespace["net_from_orig"], params.net_from_orig)
    alignments = estimate_clip(frames, horizon_row=40, strategy="chain")  # the checkpoint's data.clip
    assert any(not np.allclose(a.key_from_hist, np.eye(3)) for a in alignments[:-1])  # the history is warped
    clip = transform.apply_frames(frames, np.stack([a.key_from_hist for a in alignments]), params)
    assert np.abs(namespace["clip"][0] - clip).max() < 1e-6
    with torch.no_grad():
        logits, embedding = module.net(torch.from_numpy(clip)[None])
    assert np.abs(namespace["logits"] - logits.numpy()).max() < 1e-4
    assert np.abs(namespace["embedding"] - embedding.numpy()).max() < 1e-4
