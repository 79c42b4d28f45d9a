"""The generator split by job: the layout and settings load without the renderer, the old module path still offers
every name, and what a generation writes is written atomically."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

import stamlane.synth
import stamlane.synth.generator as old_path
from stamlane.synth import clip, config, dataset, layout, statistics, writer
from stamlane.synth.writer import write_json_lines

RENDERER = (
    "cv2",
    "tqdm",
    "stamlane.align",
    *(f"stamlane.synth.{name}" for name in ("clip", "render", "road", "vehicles", "effects", "transient")),
    *(f"stamlane.synth.{name}" for name in ("parts", "dashcam", "scenery", "bodies")),
    *(f"stamlane.synth.{name}" for name in ("statistics", "writer", "dataset", "generator")),
)
"""What draws and writes clips (with the package stamlane.align, which loads OpenCV)."""


def _loaded_after(statement: str) -> list[str]:
    """The modules of `RENDERER` (and numpy) a fresh interpreter has loaded after ``statement``."""
    code = (
        f"import json, sys\n{statement}\n"
        f"print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] == 'numpy' or m in {RENDERER!r})))\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


def test_the_layout_loads_the_standard_library_alone():
    assert _loaded_after("import stamlane.synth.layout") == []


def test_the_settings_and_factors_load_without_the_renderer():
    # what stamlane.data and stamlane.experiments import from the generator: numpy at most
    for statement in (
        "import stamlane.synth.config",
        "from stamlane.synth import FACTORS, FORMAT_VERSION, SPLITS, Factor, SynthConfig, key_frames",
        "from stamlane.synth.config import REVEAL, REVEAL_TRAFFIC, SynthConfig; SynthConfig(width=64, height=48)",
    ):
        assert not set(_loaded_after(statement)) & set(RENDERER), statement


def test_the_check_sees_the_renderer_when_it_is_loaded():
    # guard against a check that can never fail: asking the package for generate_clip loads what draws a clip
    loaded = _loaded_after("from stamlane.synth import generate_clip")
    assert {"cv2", "stamlane.synth.clip", "stamlane.synth.render"} <= set(loaded)


def test_the_old_module_path_offers_every_name_from_its_home():
    homes = (layout, config, clip, statistics, writer, dataset)
    for name in old_path.__all__:
        home = [module for module in homes if name in module.__all__]
        assert len(home) == 1, name
        assert getattr(old_path, name) is getattr(home[0], name)
    for name in stamlane.synth.__all__:
        assert getattr(stamlane.synth, name) is getattr(old_path, name)
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        _ = stamlane.synth.nothing


def test_an_interrupted_label_file_leaves_the_old_one_whole(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    path = tmp_path / "train.json"
    path.write_text('{"raw_file": "old"}\n')

    def half_then_killed(self: Path, text: str, *args: object, **kwargs: object) -> None:
        with open(self, "w") as f:
            f.write(text[: len(text) // 2])
        raise KeyboardInterrupt

    monkeypatch.setattr(Path, "write_text", half_then_killed)
    with pytest.raises(KeyboardInterrupt):
        write_json_lines(path, [{"raw_file": f"clips/train-{i:04d}/20.jpg"} for i in range(10)])
    monkeypatch.undo()
    assert path.read_text() == '{"raw_file": "old"}\n'
    assert [p.name for p in tmp_path.iterdir()] == ["train.json"]  # no temporary file left behind


def test_an_interrupted_generation_leaves_no_record_of_a_complete_set(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    root = tmp_path / "set"
    small = config.SynthConfig(width=64, height=48, num_frames=4)
    dataset.generate_dataset(root, layout.SplitCounts(train=1), config=small, progress=False)
    assert (root / "dataset.json").is_file()

    def killed(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(dataset, "write_temporal_labels", killed)  # the last step before dataset.json
    with pytest.raises(KeyboardInterrupt):
        dataset.generate_dataset(root, layout.SplitCounts(train=2), config=small, progress=False)
    assert not (root / "dataset.json").exists()  # the old set's record went first: the folder reads as incomplete
    assert not [p for p in root.rglob("*") if ".tmp" in p.name]
    assert len((root / "train.json").read_text().splitlines()) == 2  # every file whole
