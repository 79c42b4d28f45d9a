"""``stamlane predict --source``'s frames: whether a folder is one sequence, and the data module that warns."""

from __future__ import annotations

import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest

from stamlane.data.datamodule import FramesDataModule, SequenceWarning
from stamlane.data.frames import JUMP_CORRELATION, check_sequence, frame_similarity
from stamlane.data.labels import DataError
from stamlane.data.options import ClipOptions


def _real_frames(shared_dir: Path) -> Path:
    folder = shared_dir / "data" / "frames"
    if len(list(folder.glob("lanenet_*.jpg"))) < 6:
        pytest.skip(f"{folder} lacks its six real frames")
    return folder


def _driving(image: np.ndarray, frames: int, folder: Path) -> list[str]:
    """A real sequence as a camera driving forward sees it: ``image`` zoomed 4 % more a frame about a point on the
    horizon and moved 3 px sideways, written as ``folder/0.jpg, 1.jpg, ...``."""
    h, w = image.shape[:2]
    names = []
    for k in range(frames):
        s = 1 + 0.04 * k
        matrix = np.array([[s, 0, w / 2 * (1 - s) + 3 * k], [0, s, 0.4 * h * (1 - s)]])
        cv2.imwrite(str(folder / f"{k}.jpg"), cv2.warpAffine(image, matrix, (w, h), borderMode=cv2.BORDER_REFLECT))
        names.append(f"{k}.jpg")
    return names


def test_unrelated_real_frames_are_not_one_sequence(shared_dir: Path) -> None:
    """The six real highway frames (from different TuSimple clips): every pair jumps, whatever the stride."""
    folder = _real_frames(shared_dir)
    names = sorted(p.name for p in folder.glob("lanenet_*.jpg"))
    for stride in (1, 2):
        check = check_sequence(folder, names, stride)
        assert check.pairs == 6 - stride and len(check.jumps) == check.pairs and not check.one_sequence
        assert check.jumps[0][:2] == (names[0], names[stride]) and check.jumps[0][2] < JUMP_CORRELATION
        assert "jumps between" in check.problem() and (stride == 1) == ("apart" not in check.problem())


def test_a_real_sequence_and_a_synthetic_clip_are_one(shared_dir: Path, synthetic_root: Path, tmp_path: Path) -> None:
    image = cv2.imread(str(_real_frames(shared_dir) / "lanenet_0003.jpg"))
    names = _driving(image, 6, tmp_path)
    check = check_sequence(tmp_path, names)
    assert check.one_sequence and not check.jumps and check.problem() is None
    clip = synthetic_root / "clips" / "test-0000"
    names = sorted((p.name for p in clip.glob("*.jpg")), key=lambda n: int(Path(n).stem))
    for stride in (1, 2):
        assert check_sequence(clip, names, stride).one_sequence


def test_images_of_two_sizes_are_not_one_sequence(synthetic_root: Path, tmp_path: Path) -> None:
    clip = synthetic_root / "clips" / "test-0000"
    for i in (1, 2, 3):
        image = cv2.imread(str(clip / f"{i}.jpg"))
        image = cv2.resize(image, None, fx=2, fy=2) if i == 3 else image
        cv2.imwrite(str(tmp_path / f"{i}.jpg"), image)
    check = check_sequence(tmp_path, ["1.jpg", "2.jpg", "3.jpg"])
    assert not check.jumps and not check.one_sequence  # the content goes on; the size does not
    assert check.problem() == "2 image sizes (2 of 160x96, 1 of 320x192)"
    with pytest.raises(DataError, match=r"2 image sizes .*; a clip's frames share one size"):
        FramesDataModule(str(tmp_path), ClipOptions(num_frames=2, align="none")).setup("predict")
    FramesDataModule(str(tmp_path), ClipOptions(num_frames=2, align="none"), history_source="key").setup("predict")


def test_similarity_is_one_for_a_frame_and_itself_and_sees_a_shift() -> None:
    rng = np.random.default_rng(0)
    image = cv2.GaussianBlur(rng.integers(0, 255, (96, 160, 3), dtype=np.uint8), (0, 0), 4)
    assert frame_similarity(image, image) == pytest.approx(1.0)
    shifted = np.roll(image, 10, axis=1)  # 4 thumbnail px: the edge of the search
    assert frame_similarity(image, shifted) > 0.9 > frame_similarity(image, np.roll(image, 40, axis=1))
    assert frame_similarity(image, np.full_like(image, 128)) <= 0.0  # no edge at all: nothing in common
    with pytest.raises(ValueError, match="stride"):
        check_sequence(".", ["a.jpg"], 0)


def test_the_data_module_warns_when_the_history_is_used_on_unrelated_frames(shared_dir: Path) -> None:
    folder = str(_real_frames(shared_dir))
    data = FramesDataModule(folder, ClipOptions(num_frames=2, align="none"))
    with pytest.warns(SequenceWarning, match=r"is not one sequence: the content jumps between 5 of 5 frame pairs"):
        data.setup("predict")
    assert data.sequence is not None and not data.sequence.one_sequence
    for quiet in (  # each frame its own history, or no history: nothing to warn about
        FramesDataModule(folder, ClipOptions(num_frames=2, align="none"), history_source="key"),
        FramesDataModule(folder, ClipOptions(num_frames=1, align="none")),
    ):
        with warnings.catch_warnings():
            warnings.simplefilter("error", SequenceWarning)
            quiet.setup("predict")
        assert quiet.sequence is None


def test_the_data_module_refuses_a_history_a_folder_cannot_give(synthetic_root: Path) -> None:
    with pytest.raises(ValueError, match=r"history_source must be one of \('real', 'key'\) for a folder or video"):
        FramesDataModule(str(synthetic_root / "clips" / "test-0000"), history_source="other_clip")


def test_a_video_decodes_with_a_progress_bar_only_when_asked(
    synthetic_root: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``stamlane adapt --no-progress`` (`FramesDataModule(progress=False)`): a video's decoding shows no bar either."""
    frames = sorted((synthetic_root / "clips" / "test-0000").glob("*.jpg"), key=lambda p: int(p.stem))[:3]
    first = cv2.imread(str(frames[0]))
    video = tmp_path / "drive.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (first.shape[1], first.shape[0]))
    for frame in frames:
        writer.write(cv2.imread(str(frame)))
    writer.release()
    for progress in (True, False):
        data = FramesDataModule(str(video), ClipOptions(num_frames=1, align="none"), progress=progress)
        data.prepare_data()
        assert len(list(data.root.glob("*.jpg"))) == 3
        assert ("decoding drive.avi" in capsys.readouterr().err) == progress
