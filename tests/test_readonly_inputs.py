"""What a command reads stays as it was: ``fit``, ``validate``, ``predict`` (on a data root and on ``--source``) and
``align`` on a read-only data root and a read-only source folder succeed, leave every input file byte for byte and
every name as they found it, and keep the alignment pairs in the cache folder (``$STAMLANE_CACHE_DIR``), never in the
data (docs/safety.md). The suite runs as root in CI, where ``chmod a-w`` stops nothing: the snapshot of every name and
byte before and after is the real check."""

from __future__ import annotations

import os
import shutil
import stat
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from stamlane.align.cache import pair_cache_folder
from stamlane.align.user_cache import CACHE_ENV
from stamlane.cli import main
from tests.training.tiny_runs import shrunk_demo_args

REPO = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.usefixtures("plain_argv")


def _snapshot(root: Path) -> dict[str, bytes | None]:
    """Every name under ``root`` (hidden ones too) with its bytes (a folder: None)."""
    return {str(p.relative_to(root)): None if p.is_dir() else p.read_bytes() for p in sorted(root.rglob("*"))}


def _read_only(root: Path) -> None:
    for path in [root, *root.rglob("*")]:
        path.chmod(path.stat().st_mode & ~(stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH))


def _writable(root: Path) -> None:
    for path in [root, *root.rglob("*")]:
        path.chmod(path.stat().st_mode | stat.S_IWUSR)


@pytest.fixture(scope="module")
def data(tiny_synthetic: Callable[..., Path], tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """A tiny synthetic set (3 train, 1 val, 1 test clip of 4 frames, 256x144), read-only (``chmod -R a-w``)."""
    root = tmp_path_factory.mktemp("readonly") / "data"
    shutil.copytree(tiny_synthetic(256, 144, 4, train=3, val=1, test=1, challenging=0, seed=4), root)
    _read_only(root)
    yield root
    _writable(root)  # for the temporary folder's clean-up


@pytest.fixture
def work(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A writable folder to run in (relative outputs land there), with its own empty cache home."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "cache"))
    return tmp_path


def _args(root: Path, out: Path, *extra: str) -> list[str]:
    """The demo config shrunk: 2 frames at 64x128 aligned on the fly, width 1/8, 2 clips a batch."""
    return shrunk_demo_args(root, out, *extra, size="[64, 128]", width=0.125, align="fly")


def _entries(work: Path) -> int:
    return len(list((work / "cache" / "alignment").rglob("*.json")))


def test_fit_validate_and_predict_leave_a_read_only_data_root_as_it_was(data: Path, work: Path) -> None:
    before = _snapshot(data)
    assert main(["fit", *_args(data, work / "runs", "--trainer.max_steps=2", "--trainer.val_check_interval=2")]) == 0
    trained = _entries(work)
    assert trained > 0  # the pairs went to the cache folder
    (ckpt,) = (work / "runs").rglob("last.ckpt")
    assert main(["validate", *_args(data, work / "runs"), f"--ckpt_path={ckpt}"]) == 0
    assert main(["predict", *_args(data, work / "pred"), f"--ckpt_path={ckpt}"]) == 0
    assert (work / "pred" / "predictions" / "predictions.json").is_file()
    assert _entries(work) >= trained
    assert _snapshot(data) == before  # no name added, none removed, no byte changed


def test_predict_source_leaves_a_read_only_folder_as_it_was(data: Path, work: Path) -> None:
    assert main(["fit", *_args(data, work / "runs", "--trainer.max_steps=1", "--trainer.limit_val_batches=0")]) == 0
    (ckpt,) = (work / "runs").rglob("last.ckpt")
    shutil.rmtree(work / "cache")
    source = sorted((data / "clips").iterdir())[0]
    before = _snapshot(source)
    out = work / "pred"
    assert main(["predict", "--source", str(source), f"--ckpt_path={ckpt}", f"--predictions.output_dir={out}"]) == 0
    assert len(list((out / "lines").rglob("*.lines.txt"))) == 4
    assert _entries(work) == 4  # pairs 1-2, 2-3, 3-4 and frame 1 with itself (its own history), in the cache folder
    assert _snapshot(source) == before


def test_align_leaves_a_read_only_data_root_as_it_was(data: Path, work: Path) -> None:
    before = _snapshot(data)
    assert main(["align", str(data), "--cache", str(work / "aligned"), "--num-frames", "2", "--quiet"]) == 0
    assert len(list((work / "aligned").rglob("*.json"))) == 5  # one per clip folder
    assert main(["align", str(data), "--num-frames", "2", "--quiet"]) == 0  # its default: outputs/ where it runs
    assert len(list((work / "outputs" / "align" / "data").rglob("*.json"))) == 5
    assert _snapshot(data) == before


def test_a_cache_that_cannot_be_written_costs_the_estimates_and_nothing_else(
    data: Path, work: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    (work / "not-a-folder").write_text("a file where the cache home would be")
    monkeypatch.setenv(CACHE_ENV, str(work / "not-a-folder" / "cache"))
    before = _snapshot(data)
    assert main(["fit", *_args(data, work / "runs", "--trainer.max_steps=1", "--trainer.limit_val_batches=0")]) == 0
    said = [r.getMessage() for r in caplog.records if r.name == "stamlane.cache"]
    assert len(said) == 1 and "is not written (it cannot be made" in said[0], said  # once, in one line
    assert _snapshot(data) == before


def test_the_suite_keeps_its_cache_in_a_folder_of_its_own() -> None:
    """tests/conftest.py names it before any test module is imported: nothing the suite runs writes into ``~/.cache``
    (a test that wants an empty cache names its own)."""
    folder = pair_cache_folder()
    assert folder is not None and os.environ[CACHE_ENV] == str(folder.parent)
    assert folder.parent.name.startswith("stamlane-test-cache-")
    assert not folder.is_relative_to(Path.home() / ".cache")
