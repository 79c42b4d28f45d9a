"""The output guard, the size budget and the run records read back: each refusal in one line, inputs untouched."""

from __future__ import annotations

import json
import os
import re
from dataclasses import replace
from pathlib import Path

import pytest
import torch

from stamlane.experiments.demo import main as demo_main
from stamlane.experiments.runner import _verify_checkpoint, check_run_config
from stamlane.experiments.store import ExperimentError, RunStore, file_sha256
from stamlane.safety.budget import MAX_CLIP_PIXELS, BudgetError, check_clip, check_rate, check_size
from stamlane.safety.guard import (
    GuardError,
    atomic_path,
    check_outputs,
    exclusive,
    is_inside,
    read_inside,
    temporary_name,
)
from stamlane.training.run_record import RunRecord


def test_an_output_that_is_an_input_or_lies_in_a_protected_one_is_refused(tmp_path: Path) -> None:
    summary = tmp_path / "summary.json"
    summary.write_text("{}")
    link = tmp_path / "link.md"
    link.symlink_to(summary)
    with pytest.raises(GuardError, match=r"summary\.json: the output would overwrite"):
        check_outputs([summary], [summary])
    with pytest.raises(GuardError, match=r"link\.md: the output would overwrite or write into the input .*summary"):
        check_outputs([link], [summary])  # links resolved
    with pytest.raises(GuardError, match="would overwrite or write into the input"):
        check_outputs([tmp_path / "runs" / "x.png"], protected=[tmp_path])
    check_outputs([tmp_path / "other.md", temporary_name(tmp_path / "other.md")], [summary])  # fine


def test_outputs_under_a_file_folders_as_files_and_files_as_folders_are_refused(tmp_path: Path) -> None:
    (tmp_path / "file").write_text("x")
    (tmp_path / "folder").mkdir()
    os.mkfifo(tmp_path / "fifo")
    with pytest.raises(GuardError, match="a file, not a folder"):
        check_outputs([tmp_path / "file" / "out.md"])
    with pytest.raises(GuardError, match="is a folder, not a file"):
        check_outputs([tmp_path / "folder"])
    with pytest.raises(GuardError, match="is a file, not a folder"):
        check_outputs(folders=[tmp_path / "file"])
    with pytest.raises(GuardError, match="FIFO"):
        check_outputs([tmp_path / "fifo"])


def test_the_atomic_writer_keeps_the_old_file_when_the_write_fails(tmp_path: Path) -> None:
    path = tmp_path / "t.md"
    path.write_text("old")
    with pytest.raises(RuntimeError), atomic_path(path) as tmp:
        tmp.write_text("half")
        raise RuntimeError("killed")
    assert path.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["t.md"]
    with atomic_path(path) as tmp:
        tmp.write_text("new")
    assert path.read_text() == "new"


def test_a_record_is_read_only_inside_its_folder(tmp_path: Path) -> None:
    outside = tmp_path / "outside.yaml"
    outside.write_text("secret: 1\n")
    run = tmp_path / "run"
    run.mkdir()
    (run / "config.yaml").symlink_to(outside)
    with pytest.raises(GuardError, match="leads outside"):
        read_inside(run / "config.yaml", run, 1 << 20)
    with pytest.raises(ExperimentError, match="leads outside"):
        check_run_config(run)


def test_a_second_holder_of_an_output_folder_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with exclusive(tmp_path):
        with pytest.raises(GuardError, match="in use by another stamlane run"), exclusive(tmp_path):
            pass
        assert demo_main(["--quick", "--out", str(tmp_path)]) == 2  # a second demo on the same --out
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "in use by another stamlane run" in err
    with exclusive(tmp_path):  # released with its holder
        pass


def _done(folder: Path, **record: object) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "done.json").write_text(json.dumps(record))
    return folder


def test_run_records_that_link_out_or_hold_the_wrong_types_are_refused(tmp_path: Path) -> None:
    top = tmp_path / "out"
    ckpt = top / "a" / "run" / "checkpoints" / "last.ckpt"
    ckpt.parent.mkdir(parents=True)
    torch.save({"state_dict": {"w": torch.zeros(2)}}, ckpt)
    good = {"run": str(ckpt.parents[1]), "last_ckpt": str(ckpt), "frames": 4, "seed": 0, "train_minutes": 0.5}
    store = RunStore(top)
    _done(top / "a", **good)
    assert store.finished("a", {}) is not None
    _done(top / "a", **(good | {"frames": None}))
    with pytest.raises(ExperimentError, match="frames must be int >= 1, got None"):
        store.finished("a", {})
    _done(top / "a", **(good | {"scores": [1]}))
    with pytest.raises(ExperimentError, match="scores"):
        store.finished("a", {})
    elsewhere = _done(tmp_path / "elsewhere", **good) / "done.json"
    (top / "b").mkdir()
    (top / "b" / "done.json").symlink_to(elsewhere)
    with pytest.raises(ExperimentError, match="leads outside"):
        store.finished("b", {})


def test_a_truncated_checkpoint_without_its_digest_is_not_reused(tmp_path: Path) -> None:
    ckpt = tmp_path / "last.ckpt"
    torch.save({"state_dict": {"w": torch.zeros(1000)}}, ckpt)
    record = RunRecord(run=tmp_path, last_ckpt=ckpt, frames=4, seed=0, train_minutes=0.1)
    _verify_checkpoint(record, tmp_path)  # whole: reused
    _verify_checkpoint(replace(record, last_ckpt_sha256=file_sha256(ckpt)), tmp_path)
    ckpt.write_bytes(ckpt.read_bytes()[:200])
    with pytest.raises(ExperimentError, match="delete the folder"):
        _verify_checkpoint(record, tmp_path)


def test_the_budget_fits_the_paper_and_refuses_what_would_not_fit_memory() -> None:
    check_clip(5, (1080, 1920))  # the paper's longest clip at full HD
    check_clip(8, (720, 1280))
    check_size((16384, 16384))  # the evaluators' side limit
    with pytest.raises(BudgetError, match=r"num_frames must be in 1\.\.32, got 1000000"):
        check_clip(1_000_000, (80, 256))
    with pytest.raises(BudgetError, match=r"sides in 1\.\.16384"):
        check_size([100000, 100000])
    with pytest.raises(BudgetError, match=re.escape(f"over the budget of {MAX_CLIP_PIXELS:,} px")):
        check_clip(4, (16384, 16384))
    with pytest.raises(BudgetError, match="two integers"):
        check_size(["80", True])
    for fps in (float("inf"), float("nan"), 0, -1, 1e9):
        with pytest.raises(BudgetError, match="finite rate"):
            check_rate(fps)


REPO = Path(__file__).resolve().parents[2]


def test_predict_never_writes_over_a_checkpoint_named_like_its_output(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], plain_argv: None
) -> None:
    from stamlane.cli import main

    out = tmp_path / "preds"
    out.mkdir()
    ckpt = out / "predictions.json"
    torch.save({"state_dict": {}}, ckpt)
    before = ckpt.read_bytes()
    argv = ["predict", "--config", str(REPO / "configs" / "demo.yaml"), f"--ckpt_path={ckpt}"]
    argv += [f"--predictions.output_dir={out}", f"--data.root={tmp_path / 'no-set'}", "--trainer.logger=false"]
    assert main(argv) == 2
    ours = [line for line in capsys.readouterr().err.splitlines() if line.startswith("stamlane predict")]
    assert len(ours) == 1 and "would overwrite or write into the input" in ours[0], ours
    assert ckpt.read_bytes() == before


def test_a_video_source_is_decoded_afresh_never_beside_the_video(tmp_path: Path) -> None:
    import cv2
    import numpy as np

    from stamlane.data.datamodule import FramesDataModule

    video = tmp_path / "drive.mp4"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), 10.0, (128, 72))
    for i in range(3):
        writer.write(np.full((72, 128, 3), 60 * i, np.uint8))
    writer.release()
    stale = tmp_path / "drive.frames"
    stale.mkdir()
    cv2.imwrite(str(stale / "000000.jpg"), np.full((72, 128, 3), 255, np.uint8))  # an old decoding's frame
    data = FramesDataModule(str(video))
    data.prepare_data()
    assert not data.root.is_relative_to(tmp_path) and len(list(data.root.glob("*.jpg"))) == 3
    assert sorted(p.name for p in tmp_path.iterdir()) == ["drive.frames", "drive.mp4"]


def test_is_inside_resolves_dots_and_links(tmp_path: Path) -> None:
    """The one path-inside-root check (run records here, label and list paths in stamlane.data.labels)."""
    top = tmp_path / "root"
    (top / "a").mkdir(parents=True)
    (tmp_path / "rootx").mkdir()
    (top / "out").symlink_to(tmp_path / "rootx")
    assert is_inside(top, top) and is_inside(top / "a" / "f.jpg", top) and is_inside(top / "a" / ".." / "b", top)
    assert not is_inside(top / ".." / "rootx", top)  # a sibling whose name starts like the root
    assert not is_inside(top / "out" / "f.jpg", top)  # a link that leads out
    assert not is_inside(tmp_path, top)


def test_two_threads_never_share_a_temporary_name(tmp_path: Path) -> None:
    import threading

    names: list[Path] = []
    both = threading.Barrier(2)  # alive at once: their ids differ

    def name() -> None:
        both.wait()
        names.append(temporary_name(tmp_path / "entry.json"))

    workers = [threading.Thread(target=name) for _ in range(2)]
    for worker in workers:
        worker.start()
    for worker in workers:
        worker.join()
    assert len(set(names)) == 2 and all(n.suffix == ".json" and n.name.startswith(".entry.json.") for n in names)
