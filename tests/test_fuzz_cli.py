"""Fuzzing the ``stamlane`` commands (hypothesis): hostile files, links, special files, sizes and argument
combinations, one harness per command, each checked against the contract of docs/safety.md:

- exit status 0, or 2 with exactly one line on stderr and no traceback;
- nothing among the inputs changed (every input file and folder hashed before and after, links included);
- bounded time (an alarm fails a hang) and memory (the peak resident size may not grow by more than 1.5 GiB:
  a size read from a flag, a config or a checkpoint is checked against the budget before anything is allocated).

The examples are derandomized and few per command (the whole file runs in about a minute on 2 cores).
"""

from __future__ import annotations

import copy
import hashlib
import json
import os
import resource
import signal
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
from hypothesis import HealthCheck, assume, currently_in_test_context, event, example, given, settings
from hypothesis import strategies as st

from stamlane.cli import main
from stamlane.experiments.summary import Difference, ModelEntry, Summary, Value
from tests.tiny_checkpoint import save_tiny_checkpoint

REPO = Path(__file__).resolve().parents[1]
torch.set_num_threads(1)


def _settings(examples: int) -> settings:
    return settings(
        max_examples=examples,
        deadline=None,
        derandomize=True,
        database=None,
        suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
    )


# ---------------------------------------------------------------------------------------------- the contract
def _fingerprint(path: Path) -> object:
    """What a path is, links and contents included (a folder: every entry below it)."""
    if os.path.islink(path):
        return ("link", os.readlink(path), _fingerprint(path.resolve()) if path.exists() else None)
    if not os.path.lexists(path):
        return None
    if path.is_dir():
        return ("dir", tuple((p.name, _fingerprint(p)) for p in sorted(path.iterdir())))
    if path.is_file():
        return ("file", hashlib.sha256(path.read_bytes()).hexdigest())
    return ("special", os.stat(path).st_mode)


def _peak_bytes() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024  # Linux reports KiB


class _Hang(BaseException):
    """A command that ran past its time: not an ``Exception``, so no command's error boundary turns it into a
    refusal (a ``TimeoutError`` was said as one line and exit 2, and the hang passed as a refusal)."""


@contextmanager
def _bounded(seconds: int = 60) -> Iterator[None]:
    def hang(*_: object) -> None:
        raise _Hang(f"the command ran past {seconds} s (a hang: a FIFO read, an endless video)")

    previous = signal.signal(signal.SIGALRM, hang)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def _contract(capsys: pytest.CaptureFixture[str], argv: list[str], inputs: list[Path], says: str = "") -> int:
    """Run ``stamlane argv`` in-process and check the contract (a refusal's line holding ``says``); returns the exit
    status."""
    before = {p: _fingerprint(p) for p in inputs}
    peak = _peak_bytes()
    capsys.readouterr()
    with _bounded():
        code = main(argv)
    err = capsys.readouterr().err.strip()
    assert code in (0, 2), (argv, code, err)
    if currently_in_test_context():
        event(f"exit status {code}")  # --hypothesis-show-statistics: both outcomes are reached
    if code == 2:
        ours = [line for line in err.splitlines() if line.startswith("stamlane")]
        assert len(ours) == 1 and "Traceback" not in err and says in ours[0], (argv, err)
    assert _peak_bytes() - peak < 1.5 * 2**30, argv
    for p, seen in before.items():
        assert _fingerprint(p) == seen, f"{argv} changed the input {p}"
    return code


PLACES = ("fresh", "input", "link-to-input", "under-a-file", "a-folder", "a-fifo", "inside-input-folder")
"""Where an output option points: somewhere new, at an input, through a link to one, under a file, at a folder,
at a FIFO, among the inputs' folder."""


def _place(kind: str, tmp: Path, name: str, input_file: Path, input_folder: Path) -> Path:
    out = tmp / "outs" / kind / name
    out.parent.mkdir(parents=True, exist_ok=True)
    if kind == "input":
        return input_file
    if kind == "link-to-input":
        out.symlink_to(input_file)
    elif kind == "under-a-file":
        (tmp / "outs" / kind / "file").write_text("x")
        return tmp / "outs" / kind / "file" / name
    elif kind == "a-folder":
        out.mkdir()
    elif kind == "a-fifo":
        os.mkfifo(out)
    elif kind == "inside-input-folder":
        return input_folder / name
    return out


# ---------------------------------------------------------------------------------------------- report
def _summary_dict() -> dict:
    v = Value(0.5, 0.01, [0.4, 0.6], 2, 10)
    models = [
        ModelEntry("stam4", "STAM", "f4_mixed_cs_features", [], 4, 10, [], {"tusimple_f1": {"test": v}}),
        ModelEntry("single", "one frame", "f1_keyonly", [], 1, 10, [], {"tusimple_f1": {"test": v}}),
    ]
    diff = Difference("models", "stam4", "single", "test", "tusimple_f1", 0.1, [0.05, 0.15], [0.1, 0.1], [0.0, 0.2])
    return json.loads(Summary("d", {}, [0, 1], {"name": "cpu"}, False, None, models, {}, [diff]).to_json())


def _leaves(data: object, at: tuple = ()) -> list[tuple]:
    if isinstance(data, dict):
        return [at, *(p for k, v in data.items() for p in _leaves(v, (*at, k)))]
    if isinstance(data, list):
        return [at, *(p for i, v in enumerate(data) for p in _leaves(v, (*at, i)))]
    return [at]


def _set(data: dict, at: tuple, value: object) -> dict:
    if not at:
        return value  # type: ignore[return-value]
    node = data
    for key in at[:-1]:
        node = node[key]
    node[at[-1]] = value
    return data


HOSTILE_VALUES = st.sampled_from([None, "x", "", [], {}, [0.1], [1, 2, 3], -1, 1e308, True, {"a": [[[[]]]]}, 10**30])
SUMMARY_FILES = st.sampled_from(["json", "fifo", "device", "folder", "link-outside", "deep", "binary", "format-1"])


@_settings(150)
@given(
    kind=SUMMARY_FILES,
    mutations=st.lists(st.tuples(st.integers(0, 10**6), HOSTILE_VALUES), max_size=3),
    outs=st.lists(st.sampled_from(PLACES), min_size=3, max_size=3),
    use=st.lists(st.booleans(), min_size=3, max_size=3),
    index=st.sampled_from([None, "tag", "not-a-mapping", "rows-not-mappings", "fifo"]),
)
def test_report(
    capsys: pytest.CaptureFixture[str],
    kind: str,
    mutations: list[tuple[int, object]],
    outs: list[str],
    use: list[bool],
    index: str | None,
) -> None:
    with tempfile.TemporaryDirectory() as folder:
        tmp = Path(folder)
        data = _summary_dict()
        if kind == "format-1":
            data = {"seeds": [0], "models": [{"name": "a", "test": {"f1_mean": 0.5}}]}
        for pick, value in mutations:  # each replaces one node of what the previous ones left
            paths = _leaves(data)
            data = _set(data, paths[pick % len(paths)], copy.deepcopy(value))  # never a shared node (a cycle)
        summary = tmp / "data" / "summary.json"
        summary.parent.mkdir()
        outside = tmp / "outside.json"
        outside.write_text(json.dumps(_summary_dict()))
        if kind in ("json", "format-1"):
            summary.write_text(json.dumps(data))
        elif kind == "fifo":
            os.mkfifo(summary)
        elif kind == "device":
            summary = Path("/dev/zero")
        elif kind == "folder":
            summary.mkdir()
        elif kind == "link-outside":
            summary.symlink_to(outside)
        elif kind == "deep":
            summary.write_text("[" * 100_000 + "]" * 100_000)
        else:
            summary.write_bytes(bytes(range(256)) * 4)
        argv = ["report", str(summary)]
        for option, place, on in zip(("--out", "--csv", "--plot"), outs, use):
            if on:
                name = {"--out": "t.md", "--csv": "s.csv", "--plot": "h.png"}[option]
                argv += [option, str(_place(place, tmp, name, summary, summary.parent))]
        inputs = [summary, outside]  # tables may go beside the summary; the summary itself stays
        if index is not None:
            path = tmp / "index.yaml"
            if index == "fifo":
                os.mkfifo(path)
            else:
                path.write_text(
                    {
                        "tag": "tables: !!python/object/apply:os.system ['echo pwned']\n",
                        "not-a-mapping": "tables: 5\n",
                        "rows-not-mappings": "tables: {1: {metrics: tusimple, rows: [5]}}\n",
                    }[index]
                )
            argv += ["--paper", "--index", str(path)]
            inputs.append(path)
        _contract(capsys, argv, inputs)


# ---------------------------------------------------------------------------------------------- show
@pytest.fixture(scope="module")
def tiny_set(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from stamlane.synth import SynthConfig, generate_dataset
    from stamlane.synth.layout import SplitCounts

    root = tmp_path_factory.mktemp("set")
    config = SynthConfig(width=128, height=72, num_frames=4)
    generate_dataset(root, SplitCounts(train=1), seed=1, config=config, progress=False)
    line = json.loads((root / "train.json").read_text().splitlines()[0])
    (root / "long.json").write_text(json.dumps(line | {"raw_file": "clips/" + "a" * 300 + "/4.jpg"}) + "\n")
    (root / "junk.json").write_bytes(b"\x00\xff{" * 50)
    (root / "strings.json").write_text(json.dumps(line | {"lanes": [["1", True]]}) + "\n")
    os.mkfifo(root / "fifo.json")
    outside = tmp_path_factory.mktemp("outside") / "labels.json"
    outside.write_text((root / "train.json").read_text())
    (root / "link-out.json").symlink_to(outside)
    return root


@_settings(80)
@given(
    labels=st.sampled_from(
        ["train.json", "long.json", "junk.json", "strings.json", "fifo.json", "missing.json", "link-out.json"]
    ),
    size=st.sampled_from(["64x32", "65536x65536", "16384x16384", "0x4", "axb", "8192x8192"]),
    frames=st.sampled_from([1, 2, 33, 10**6, 0, -1]),
    n=st.sampled_from([1, 0, 10**9]),
    out=st.sampled_from(PLACES),
)
@example(labels="train.json", size="64x32", frames=2, n=1, out="fresh")  # the run that succeeds
def test_show(
    tiny_set: Path, capsys: pytest.CaptureFixture[str], labels: str, size: str, frames: int, n: int, out: str
) -> None:
    with tempfile.TemporaryDirectory() as folder:
        target = _place(out, Path(folder), "grid.png", tiny_set / "train.json", tiny_set)
        argv = ["show", "--root", str(tiny_set), "--labels", labels, "--out", str(target)]
        argv += ["--size", size, "--num-frames", str(frames), "--n", str(n), "--align", "none"]
        _contract(capsys, argv, [tiny_set])


# ---------------------------------------------------------------------------------------------- stream


@pytest.fixture(scope="module")
def stream_inputs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A checkpoint as `stamlane fit` writes it, one whose recorded T is 100,000, and a folder of 3 frames."""
    folder = tmp_path_factory.mktemp("stream")
    found = {
        name: save_tiny_checkpoint(folder / f"{name}.ckpt", frames) for name, frames in (("good", 2), ("huge", 100_000))
    }
    frames_dir = folder / "frames"
    frames_dir.mkdir()
    for i in range(3):
        cv2.imwrite(str(frames_dir / f"{i}.jpg"), np.full((72, 128, 3), 40 * i, np.uint8))
    found["frames"] = frames_dir
    video = folder / "drive.mp4"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), 10.0, (128, 72))
    for i in range(3):
        writer.write(np.full((72, 128, 3), 40 * i, np.uint8))
    writer.release()
    found["video"] = video
    (folder / "link-to-frames").symlink_to(frames_dir)
    found["link"] = folder / "link-to-frames"
    os.mkfifo(folder / "fifo.mp4")
    found["fifo"] = folder / "fifo.mp4"
    return found


@_settings(80)
@given(
    ckpt=st.sampled_from(["good", "huge"]),
    fps=st.sampled_from([None, "inf", "nan", "-5", "0", "1e9", "10"]),
    frames=st.sampled_from([None, 1, 2, 10**6, 0]),
    size=st.sampled_from([None, (32, 64), (65536, 65536), (63, 5)]),
    out=st.sampled_from([*PLACES, "ckpt-named-like-output", "another-sources-folder"]),
    video=st.booleans(),
    source=st.sampled_from(["frames", "video", "link", "fifo"]),
    preset=st.sampled_from([None, "fast", "quick"]),
)
@example(ckpt="good", fps=None, frames=None, size=None, out="fresh", video=False, source="frames", preset=None)
@example(ckpt="good", fps="10", frames=2, size=(32, 64), out="fresh", video=True, source="video", preset="fast")
def test_stream(
    stream_inputs: dict[str, Path],
    capsys: pytest.CaptureFixture[str],
    ckpt: str,
    fps: str | None,
    frames: int | None,
    size: tuple[int, int] | None,
    out: str,
    video: bool,
    source: str,
    preset: str | None,
) -> None:
    source_path = stream_inputs[source]
    with tempfile.TemporaryDirectory() as folder:
        tmp = Path(folder)
        checkpoint = stream_inputs[ckpt]
        if out == "ckpt-named-like-output":  # a checkpoint in --out named like the command's output
            target = tmp / "run"
            target.mkdir()
            checkpoint = target / "lanes.jsonl"
            checkpoint.write_bytes(stream_inputs[ckpt].read_bytes())
        elif out == "another-sources-folder":  # the results of another source: never written beside
            from stamlane.safety.owner import mark

            target = tmp / "theirs"
            mark(target, {"command": "stream", "source": str(tmp / "elsewhere.mp4")})
            (target / "lanes.jsonl").write_text("theirs\n")
        else:
            target = _place(out, tmp, "stream", stream_inputs["video"], stream_inputs["frames"])
        argv = ["stream", str(source_path), "--ckpt", str(checkpoint), "--out", str(target), "--max-frames", "2"]
        argv += [] if fps is None else [f"--fps={fps}"]
        argv += [] if frames is None else ["--num-frames", str(frames)]
        argv += [] if size is None else ["--image-size", *map(str, size)]
        argv += [] if video else ["--no-video"]
        argv += [] if preset is None else ["--align-preset", preset]
        inputs = [stream_inputs[k] for k in ("frames", "video", "link", "good", "huge")]
        code = _contract(capsys, argv, [*inputs, checkpoint, *([target] if out == "another-sources-folder" else [])])
        assert code == 2 or out != "another-sources-folder"
        ok = source in ("frames", "video", "link") and (ckpt, fps in (None, "10"), out) == ("good", True, "fresh")
        ok = ok and preset != "quick"  # not a preset: one line, status 2
        if ok and frames in (None, 2) and size in (None, (32, 64)):
            assert code == 0 and (target / "lanes.jsonl").is_file()  # what is valid is done


ADAPT_FLAGS = [
    ("--steps", "99999999999"),
    ("--steps", "0"),
    ("--lr", "nan"),
    ("--fusion-lr-scale", "inf"),
    ("--real-batch", "100000"),
    ("--synthetic-batch", "-1"),
    ("--real-weight", "-1"),
    ("--hi", "2"),
    ("--min-agree", "1000000"),
    ("--tolerance", "100000"),
    ("--threads", "99999"),
    ("--synthetic-clips", "10000000"),
    ("--max-frames", "0"),
]
"""Flags of ``stamlane adapt`` with values that would size an endless run, a batch past memory or no number."""
ADAPT_OUTS = ("fresh", "input", "link-to-input", "under-a-file", "a-fifo")


@_settings(60)
@given(
    ckpt=st.sampled_from(["good", "huge", "fifo", "frames", "missing"]),
    source=st.sampled_from(["frames", "video", "link", "fifo", "missing"]),
    flags=st.lists(st.sampled_from(ADAPT_FLAGS), max_size=2),
    out=st.sampled_from(ADAPT_OUTS),
)
@example(ckpt="good", source="video", flags=[("--steps", "99999999999")], out="fresh")  # an endless run, refused
@example(ckpt="huge", source="frames", flags=[], out="fresh")  # a recorded T of 100,000
@example(ckpt="good", source="video", flags=[], out="input")  # over the checkpoint
def test_adapt(
    stream_inputs: dict[str, Path], capsys: pytest.CaptureFixture[str], ckpt: str, source: str, flags: list, out: str
) -> None:
    """Every hostile input of ``stamlane adapt`` (a flag out of its bounds, a checkpoint or source that is no
    checkpoint or source, an output over or under an input) is one line and exit 2 before any work, inputs unchanged.
    A valid command trains: those are `tests/training/test_adapt.py`'s, so every example here holds a hostile part."""
    assume(flags or out != "fresh" or ckpt != "good" or source not in ("frames", "video", "link"))
    with tempfile.TemporaryDirectory() as folder:
        tmp = Path(folder)
        checkpoint = stream_inputs.get(ckpt, tmp / "missing.ckpt")
        target = _place(out, tmp, "adapt", stream_inputs["good"], stream_inputs["frames"])
        argv = ["adapt", "--ckpt_path", str(checkpoint), "--source", str(stream_inputs.get(source, tmp / "none.mp4"))]
        argv += ["--out", str(target), "--no-progress", "--threads", "1", *(v for flag in flags for v in flag)]
        inputs = [stream_inputs[k] for k in ("frames", "video", "link", "good", "huge")]
        assert _contract(capsys, argv, inputs) == 2


@_settings(40)
@given(
    source=st.sampled_from(["frames", "video", "link"]),
    tusimple=st.booleans(),
    culane=st.booleans(),
    sequence=st.sampled_from([None, "seq", "clips/0531", "../up", "/abs", "", "a//b", ".", "a\nb", "a\x00b"]),
    first=st.sampled_from([None, "1.jpg", "000000.png", "x.jpg", "../1.jpg", "9" * 20 + ".jpg", "1"]),
    rows=st.sampled_from([None, (0, 72, 10), (10, 5, 1), (0, 10**9, 1), (0, 10, 0), (-5, 10, 1)]),
    out=st.sampled_from(["fresh", "input", "under-a-file", "inside-input-folder", "lines-is-a-file"]),
)
@example(
    source="video", tusimple=True, culane=True, sequence="clips/0531", first="1.jpg", rows=(0, 72, 10), out="fresh"
)
@example(source="frames", tusimple=True, culane=True, sequence=None, first=None, rows=None, out="fresh")  # succeeds
def test_stream_evaluator_outputs(
    stream_inputs: dict[str, Path],
    capsys: pytest.CaptureFixture[str],
    source: str,
    tusimple: bool,
    culane: bool,
    sequence: str | None,
    first: str | None,
    rows: tuple[int, int, int] | None,
    out: str,
) -> None:
    """The flags of ``--tusimple`` / ``--culane`` output: names that would leave the output folder, absurd rows,
    outputs in the way; each refused in one line, nothing beside an input."""
    with tempfile.TemporaryDirectory() as folder:
        tmp = Path(folder)
        if out == "lines-is-a-file":
            target = tmp / "run"
            target.mkdir()
            (target / "lines").write_text("x")
        else:
            target = _place(out, tmp, "stream", stream_inputs["video"], stream_inputs["frames"])
        argv = ["stream", str(stream_inputs[source]), "--ckpt", str(stream_inputs["good"]), "--out", str(target)]
        argv += ["--max-frames", "2", "--no-video", *(["--tusimple"] if tusimple else [])]
        argv += ["--culane"] if culane else []
        argv += [] if sequence is None else ["--sequence", sequence]
        argv += [] if first is None else ["--first-frame", first]
        argv += [] if rows is None else ["--h-samples", *map(str, rows)]
        inputs = [stream_inputs[k] for k in ("frames", "video", "link", "good")]
        code = _contract(capsys, argv, inputs)
        names_ok = sequence in (None, "seq", "clips/0531") and (first is None or (first in ("1.jpg", "000000.png")))
        named = (tusimple or culane) or (sequence is None and first is None)
        ok = names_ok and named and (first is None or source == "video") and rows in (None, (0, 72, 10))
        if ok and out == "fresh":
            assert code == 0, argv
            assert (target / "predictions.json").is_file() == tusimple and (target / "lines").is_dir() == culane
            if culane:  # every file inside the output folder, under the sequence
                for path in (target / "lines").rglob("*.lines.txt"):
                    assert path.resolve().is_relative_to((target / "lines").resolve())
        if code == 0:
            assert not list(target.glob(".*tmp*")), list(target.iterdir())


@_settings(25)
@given(
    device=st.one_of(
        st.sampled_from(["cpu", "auto", "cuda", "cuda:9", "cuda:-1", "meta", "tpu", ""]), st.text(max_size=12)
    )
)
@example(device="cpu")  # succeeds
def test_stream_device(stream_inputs: dict[str, Path], capsys: pytest.CaptureFixture[str], device: str) -> None:
    """``--device``: any string is a device this machine has (the network runs there) or one line, exit 2, nothing
    written."""
    with tempfile.TemporaryDirectory() as folder:
        target = Path(folder) / "run"
        argv = ["stream", str(stream_inputs["frames"]), "--ckpt", str(stream_inputs["good"]), "--out", str(target)]
        argv += ["--max-frames", "2", "--no-video", f"--device={device}"]
        code = _contract(capsys, argv, [stream_inputs[k] for k in ("frames", "good")])
        if device in ("cpu", "auto"):
            assert code == 0, argv
        if code == 2:
            assert not target.exists()


# ---------------------------------------------------------------------------------------------- synth
@_settings(60)
@given(
    size=st.sampled_from(["64x48", "100000x100000", "8192x8192", "10x10"]),
    frames=st.sampled_from([2, 10**6, 0]),
    fps=st.sampled_from(["inf", "nan", "0", "20", "1e12"]),
    clips=st.sampled_from([1, 0, -1]),
    out=st.sampled_from(["fresh", "existing-set", "under-a-file", "a-file", "a-fifo", "foreign-folder"]),
    world=st.sampled_from(["classic", "dashcam2", "dashcam3", "nowhere"]),
    labels=st.sampled_from(["all", "adjacent", "nearest", ""]),
)
@example(size="64x48", frames=2, fps="20", clips=1, out="fresh", world="classic", labels="all")  # the run that succeeds
@example(size="64x48", frames=2, fps="20", clips=1, out="fresh", world="dashcam3", labels="adjacent")  # the newest too
@example(size="64x48", frames=2, fps="20", clips=1, out="foreign-folder", world="classic", labels="all")  # not there
def test_synth(
    tiny_set: Path,
    capsys: pytest.CaptureFixture[str],
    size: str,
    frames: int,
    fps: str,
    clips: int,
    out: str,
    world: str,
    labels: str,
) -> None:
    with tempfile.TemporaryDirectory() as folder:
        tmp = Path(folder)
        target = {
            "fresh": tmp / "new",
            "existing-set": tiny_set,
            "under-a-file": tiny_set / "train.json" / "set",
            "a-file": tiny_set / "train.json",
            "a-fifo": tiny_set / "fifo.json",
            "foreign-folder": tmp / "frames",  # frames and test_label.json: no name of a set synth writes
        }[out]
        if out == "foreign-folder":
            (tmp / "frames").mkdir()
            (tmp / "frames" / "0.jpg").write_bytes(b"frame")
            (tmp / "frames" / "test_label.json").write_text("{}\n")
        argv = ["synth", "--out", str(target), "--size", size, "--frames", str(frames), f"--fps={fps}"]
        argv += [
            "--clips",
            str(clips),
            "--challenging-clips",
            "0",
            "--quiet",
            "--world",
            world,
            "--label-lanes",
            labels,
        ]
        code = _contract(capsys, argv, [tiny_set, tmp / "frames"])
        valid = world != "nowhere" and labels in ("all", "adjacent")
        assert code == 2 or (out not in ("foreign-folder", "existing-set") and valid)
        if (size, frames, fps, clips, out) == ("64x48", 2, "20", 1, "fresh") and valid:
            assert code == 0 and (target / "train.json").is_file()  # what is valid is done


# ---------------------------------------------------------------------------------------------- demo --quick
@_settings(40)
@given(
    data=st.sampled_from(["tusimple-set", "a-file", "a-fifo", "is-out"]),
    out=st.sampled_from(["fresh", "inside-data", "under-a-file", "a-file"]),
    seeds=st.sampled_from([1, 0, -3]),
)
def test_demo_quick(capsys: pytest.CaptureFixture[str], data: str, out: str, seeds: int) -> None:
    """Arguments a careless or hostile user gives ``demo --quick``: every one is refused before anything is
    trained or written (a valid run is `tests/experiments/test_demo.py`'s)."""
    with tempfile.TemporaryDirectory() as folder:
        tmp = Path(folder)
        tusimple = tmp / "tusimple"
        (tusimple / "clips" / "0").mkdir(parents=True)
        (tusimple / "train.json").write_text('{"raw_file": "clips/0/20.jpg", "lanes": [], "h_samples": []}\n')
        (tusimple / "clips" / "0" / "20.jpg").write_bytes(b"frame")
        (tmp / "file").write_text("x")
        os.mkfifo(tmp / "fifo")
        root = {"tusimple-set": tusimple, "a-file": tmp / "file", "a-fifo": tmp / "fifo", "is-out": tusimple}[data]
        target = {
            "fresh": tmp / "out",
            "inside-data": tusimple / "out",
            "under-a-file": tmp / "file" / "out",
            "a-file": tmp / "file",
        }[out]
        if data == "is-out":
            target = tusimple
        argv = ["demo", "--quick", "--data", str(root), "--out", str(target), "--seeds", str(seeds)]
        assert _contract(capsys, argv, [tusimple, tmp / "file", tmp / "fifo"]) == 2


# ---------------------------------------------------------------------------------------------- demo: --splits
@_settings(40)
@given(
    command=st.sampled_from(["demo", "ablate"]),
    split=st.sampled_from(["../outside", "/etc/passwd", "", "a/b", "x" * 300, "..", "-", "challenging-frames"]),
    probe=st.sampled_from(["key", "../x", "", "future", "exact"]),
)
def test_splits_and_probes(capsys: pytest.CaptureFixture[str], command: str, split: str, probe: str) -> None:
    """``--splits`` names a label file's stem in the data root (never a path out of it) and ``--reveal-probes`` one
    of the probes: anything else is one line, exit status 2, before any data is read or made (the demo refuses the
    frame-after-frame scoring alone too)."""
    with tempfile.TemporaryDirectory() as folder:
        tmp = Path(folder)
        (tmp / "outside.json").write_text("{}\n")
        argv = [command, "--out", str(tmp / "out"), "--splits", split]
        if command == "demo":
            argv += ["--reveal-probes", probe]
        if command == "ablate" and split == "challenging-frames":
            return  # a valid name for ablate, which goes on to its data root (tests/test_ablate.py)
        assert _contract(capsys, argv, [tmp / "outside.json"]) == 2
        assert not (tmp / "out").exists()


@_settings(40)
@given(
    command=st.sampled_from(["demo", "ablate"]),
    section=st.sampled_from(["trainer", "model", "data", "eval", "zz"]),
    key=st.text(alphabet="abcdefghijklmnopqrstuvwxyz_.", max_size=12),
    value=st.text(max_size=12),
    bare=st.booleans(),
)
def test_fit_arguments_after_the_double_dash(
    capsys: pytest.CaptureFixture[str], command: str, section: str, key: str, value: str, bare: bool
) -> None:
    """What follows ``--`` goes to every run's ``stamlane fit``: an argument it would refuse (an unknown key, a bare
    word) is one line, exit status 2, before any data is made or ``--out`` written."""
    extra = [f"zz{value}"] if bare else [f"--{section}.zz{key}={value}"]  # ``zz``: no option starts so
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "out"
        argv = [command, "--out", str(out), *(["--table", "2"] if command == "ablate" else ["--quick"]), "--", *extra]
        assert _contract(capsys, argv, []) == 2
        assert not out.exists()


# ---------------------------------------------------------------------------------------------- demo: records
RECORD_VALUES = st.sampled_from([None, "x", 3, 2.5, True, [], {}, [1], {"a": 1}, "/etc/passwd", "../../outside"])
RECORD_KINDS = st.sampled_from(["json", "link-outside", "fifo", "deep", "binary", "folder-linked", "truncated-ckpt"])


@_settings(80)
@given(
    kind=RECORD_KINDS,
    changes=st.dictionaries(
        st.sampled_from(["run", "last_ckpt", "frames", "scores", "labels", "last_ckpt_sha256", "data"]),
        RECORD_VALUES,
        max_size=3,
    ),
)
def test_demo_run_records(kind: str, changes: dict[str, object]) -> None:
    """What a resumed ``stamlane demo`` / ``ablate`` reads back from a run folder (``done.json``, the checkpoint
    it names): a record that is hostile in kind or value is refused in one line (`ExperimentError`),
    one that is used holds the types it is used with, and nothing outside the experiment's folder is read."""
    from stamlane.experiments.runner import _verify_checkpoint
    from stamlane.experiments.store import ExperimentError, RunStore, file_sha256

    with tempfile.TemporaryDirectory() as folder:
        tmp = Path(folder)
        top, name = tmp / "out", "a-s0"
        run = top / name / "run"
        ckpt = run / "checkpoints" / "last.ckpt"
        ckpt.parent.mkdir(parents=True)
        torch.save({"state_dict": {"w": torch.zeros(64)}}, ckpt)
        record = {"data": "d", "run": str(run), "last_ckpt": str(ckpt), "frames": 4, "scores": {}, "labels": {}}
        record |= {"last_ckpt_sha256": file_sha256(ckpt)} | changes
        if kind == "truncated-ckpt":  # cut short, and its digest taken out of the record
            ckpt.write_bytes(ckpt.read_bytes()[:100])
            record.pop("last_ckpt_sha256", None)
        outside = tmp / "outside.json"
        outside.write_text(json.dumps(record))
        done = top / name / "done.json"
        if kind in ("json", "truncated-ckpt"):
            done.write_text(json.dumps(record))
        elif kind == "link-outside":
            done.symlink_to(outside)
        elif kind == "fifo":
            os.mkfifo(done)
        elif kind == "deep":
            done.write_text("{" + '"a":{' * 50_000 + "}" * 50_001)
        elif kind == "binary":
            done.write_bytes(bytes(range(256)))
        else:  # the run folder itself a link to a folder outside the experiment
            elsewhere = tmp / "elsewhere"
            elsewhere.mkdir()
            (elsewhere / "done.json").write_text(json.dumps(record))
            (top / "b-s0").symlink_to(elsewhere)
            name = "b-s0"
        seen = _fingerprint(outside)
        with _bounded(30):
            try:
                got = RunStore(top).finished(name, {"data": "d"})
                if got is not None:
                    _verify_checkpoint(got, top / name)
            except ExperimentError as err:
                assert len(str(err).splitlines()) == 1
                got = None
        if got is not None:  # what is reused holds what it is used with, inside the experiment
            assert isinstance(got.frames, int) and not isinstance(got.frames, bool)
            assert Path(got["run"]).resolve().is_relative_to(top.resolve())
            assert kind not in ("link-outside", "folder-linked", "truncated-ckpt", "fifo", "deep", "binary")
        assert _fingerprint(outside) == seen


# ---------------------------------------------------------------------------------------------- fit / predict
@pytest.fixture
def plain_argv_module(monkeypatch: pytest.MonkeyPatch) -> None:
    import sys

    monkeypatch.setattr(sys, "argv", ["stamlane"])


HOSTILE_CONFIGS = {
    "data:\n  clip: {num_frames: 1000000}\n": "num_frames must be in 1..32",
    "data:\n  clip: {image_size: [100000, 100000]}\n": "sides in 1..16384",
    "data:\n  synth: {size: [100000, 100000]}\n": "sides in 1..16384",
    "data:\n  num_frames: 1\n  clip: {num_frames: 2}\n": "give one of them",
    "data:\n  loader: [1, 2]\n": "must be a mapping",
    "data:\n  loader: {memory_mb: -1}\n": "memory_mb must be >= 0",
    "data:\n  loader: {memory_mb: many}\n": "memory_mb",
    "data:\n  clip: {num_frames: 4, image_size: [16384, 16384]}\n": "over the budget",
    "data: !!python/object/apply:os.system ['echo pwned']\n": "python/object",
    "data:\n  augment: {strides: [1, 0]}\n": "strides must all be >= 1",
    "data:\n  augment: {strides: [one, four]}\n": "strides",
}
"""Config values a careless or hostile user gives: sizes past the budget, conflicting and mistyped values, a tag."""


@pytest.mark.parametrize("config", list(HOSTILE_CONFIGS))
def test_fit_and_predict_config_values(
    plain_argv_module: None, capsys: pytest.CaptureFixture[str], config: str
) -> None:
    """Sizes and types from a config: refused in one line before anything is allocated or trained."""
    with tempfile.TemporaryDirectory() as folder:
        tmp = Path(folder)
        path = tmp / "hostile.yaml"
        path.write_text(config)
        command = ("fit", "predict")[list(HOSTILE_CONFIGS).index(config) % 2]
        argv = [command, "--config", str(REPO / "configs" / "demo.yaml"), "--config", str(path)]
        argv += [f"--trainer.default_root_dir={tmp / 'run'}", "--trainer.logger=false", "--trainer.max_steps=1"]
        argv += [f"--data.root={tmp / 'no-set'}"]  # never a default set generated in the working folder
        capsys.readouterr()
        before = _fingerprint(path)
        with _bounded():
            code = main(argv)
        err = capsys.readouterr().err.strip().splitlines()
        ours = [line for line in err if line.startswith(f"stamlane {command}")]
        assert code == 2 and len(ours) == 1 and HOSTILE_CONFIGS[config] in ours[0], err
        assert _fingerprint(path) == before


# ---------------------------------------------------------------------------------------------- every path option
PATH_SHAPES = (
    "long-name",  # one component over the file system's 255 bytes (Path.exists() raises on Python 3.11)
    "long-component",  # a long component in the middle of the path
    "long-path",  # over 4,096 bytes in all, each component short
    "fifo",
    "device",  # /dev/zero: never ends
    "sparse",  # a 2 GiB file that takes no disk (read whole: a MemoryError or 2 GiB of memory)
    "link-loop",
    "dangling-link",
    "dot-segments",  # a/./b/../missing
    "not-utf8",  # a folder whose name holds bytes that are not UTF-8
    "nul-byte",
    "under-a-file",
)
"""Path shapes every path option of every command must answer in one line (exit 2), never a traceback, a hang or
a blown memory."""


def _shape(kind: str, tmp: Path, name: str) -> str:
    """A path of the shape ``kind`` under ``tmp`` (made there when it is a file, a link or a folder)."""
    if kind == "long-name":
        return str(tmp / ("n" * 300 + name))
    if kind == "long-component":
        return str(tmp / ("c" * 256) / name)
    if kind == "long-path":
        return str(tmp.joinpath(*["p" * 200] * 22, name))
    if kind == "fifo":
        path = tmp / f"fifo-{name}"
        if not path.exists():
            os.mkfifo(path)
        return str(path)
    if kind == "device":  # an output gets a link to it: a command that replaced its output would replace the link,
        if name.startswith("out"):  # never the device node itself (a test run as root must not lose /dev/zero)
            link = tmp / f"device-{name}"
            if not os.path.lexists(link):
                link.symlink_to("/dev/zero")
            return str(link)
        return "/dev/zero"
    if kind == "sparse":
        path = tmp / f"sparse-{name}"
        with open(path, "wb") as file:
            file.truncate(2 << 30)
        return str(path)
    if kind == "link-loop":
        a, b = tmp / f"loop-a-{name}", tmp / f"loop-b-{name}"
        if not os.path.lexists(a):
            a.symlink_to(b)
            b.symlink_to(a)
        return str(a)
    if kind == "dangling-link":
        path = tmp / f"dangling-{name}"
        if not os.path.lexists(path):
            path.symlink_to(tmp / "nothing-here")
        return str(path)
    if kind == "dot-segments":
        return f"{tmp}/./a/../b//./missing-{name}"
    if kind == "not-utf8":
        path = os.fsencode(tmp) + b"/\xff\xfe-" + name.encode()
        os.makedirs(path, exist_ok=True)
        return os.fsdecode(path)
    if kind == "nul-byte":
        return f"{tmp}/nul\x00{name}"
    (tmp / "a-file").write_text("x")
    return str(tmp / "a-file" / name)


PATH_COMMANDS = {
    "fit-config": ["fit", "--config", "{path}"],
    "validate-ckpt": ["validate", "--ckpt_path", "{path}"],
    "predict-ckpt": ["predict", "--ckpt_path", "{path}", "--source", "{frames}"],
    "predict-source": ["predict", "--source", "{path}", "--ckpt_path", "{ckpt}"],
    "predict-config": ["predict", "--config={path}", "--source", "{frames}"],
    "stream-source": ["stream", "{path}", "--ckpt", "{ckpt}", "--out", "{tmp}/s", "--no-video"],
    "stream-ckpt": ["stream", "{frames}", "--ckpt", "{path}", "--out", "{tmp}/s", "--no-video"],
    "stream-out": ["stream", "{frames}", "--ckpt", "{ckpt}", "--out", "{path}", "--no-video", "--max-frames", "1"],
    "export-ckpt": ["export", "--ckpt_path", "{path}", "--out", "{tmp}/m.onnx"],
    "show-root": ["show", "--root", "{path}", "--out", "{tmp}/g.png"],
    "show-out": ["show", "--root", "{set}", "--labels", "train.json", "--out", "{path}", "--n", "1"],
    "align-root": ["align", "{path}", "--cache", "{tmp}/cache", "--quiet"],
    "synth-out": ["synth", "--out", "{path}", "--clips", "1", "--challenging-clips", "0", "--quiet"],
    "report-summary": ["report", "{path}"],
    "report-out": ["report", "{summary}", "--out", "{path}"],
    "demo-data": ["demo", "--quick", "--data", "{path}", "--out", "{tmp}/d"],
    "demo-out": ["demo", "--quick", "--out", "{path}"],
    "demo-fit-config": ["demo", "--quick", "--out", "{tmp}/d", "--", "--config", "{path}"],
    "ablate-base": ["ablate", "--table", "2", "--base", "{path}", "--out", "{tmp}/a"],
    "ablate-out": ["ablate", "--table", "2", "--out", "{path}", "--data", "{path}"],
    "ablate-fit-config": ["ablate", "--table", "2", "--out", "{tmp}/a", "--", "--config={path}"],
}
"""Every command of ``stamlane`` with each of its path options as ``{path}``; the other paths valid."""
OUTPUT_SHAPES = ("long-name", "long-component", "long-path", "fifo", "device", "link-loop", "nul-byte", "under-a-file")
"""The shapes an output option is fuzzed with (every one refused: a valid output would run the whole command)."""


@pytest.fixture(scope="module")
def path_inputs(tmp_path_factory: pytest.TempPathFactory, stream_inputs: dict[str, Path], tiny_set: Path) -> dict:
    folder = tmp_path_factory.mktemp("paths")
    summary = folder / "summary.json"
    summary.write_text(json.dumps(_summary_dict()))
    return {"frames": stream_inputs["frames"], "ckpt": stream_inputs["good"], "set": tiny_set, "summary": summary}


@pytest.mark.parametrize("command", sorted(PATH_COMMANDS))
@_settings(5)
@given(data=st.data())
def test_every_path_option_answers_every_path_shape(
    path_inputs: dict[str, Path],
    plain_argv_module: None,
    capsys: pytest.CaptureFixture[str],
    command: str,
    data: st.DataObject,
) -> None:
    """Property: a path of any shape given to any path option of any command is one line and exit status 2 (the
    path gate, `stamlane.safety.paths`), never a traceback, a hang, 2 GiB read or a file written beside it."""
    shapes = OUTPUT_SHAPES if command.endswith("-out") else PATH_SHAPES
    if command == "demo-data":  # a missing --data is where the synthetic set is made: a path with dots is valid
        shapes = tuple(s for s in shapes if s != "dot-segments")
    kind = data.draw(st.sampled_from(shapes), label="shape")
    with tempfile.TemporaryDirectory() as folder:
        tmp = Path(folder)
        path = _shape(kind, tmp, "x.yaml" if "config" in command else "out-x" if command.endswith("-out") else "x")
        values = {k: str(v) for k, v in path_inputs.items()} | {"tmp": str(tmp), "path": path}
        argv = [a.format(**values) for a in PATH_COMMANDS[command]]
        inputs = [path_inputs[k] for k in ("frames", "ckpt", "summary")]
        assert _contract(capsys, argv, inputs) == 2, (command, kind)
        made = {p.name for p in tmp.iterdir()} - {"a-file", "a", "b"}
        assert not {"s", "m.onnx", "g.png", "d", "cache"} & made, (command, kind, made)


# ---------------------------------------------------------------------------------------------- paths inside configs
CONFIG_PATH_KEYS = {
    "data.root": ("fit", "data:\n  root: {path}\n"),
    "model.init_weights": ("fit", "model:\n  init_weights: {path}\n"),
    "model.encoder.init_args.weights": ("fit", "model:\n  encoder:\n    init_args:\n      weights: {path}\n"),
    "predictions.output_dir": ("predict", "predictions:\n  output_dir: {path}\n"),
    "ckpt_path": ("validate", "ckpt_path: {path}\n"),
}
"""A path-valued option of each kind (a data folder, a weights file, an output folder, a checkpoint) written in a
``--config`` file, with the command that reads it."""
GATED_SHAPES = ("long-name", "long-component", "long-path", "fifo", "device", "link-loop", "nul-byte")
"""The path shapes the gate itself refuses (the others are missing paths, said by their readers; a name that is not
UTF-8 cannot be written in a YAML file: its escape is refused by the YAML reader, in one line)."""


@pytest.mark.parametrize("key", list(CONFIG_PATH_KEYS))
@_settings(3)
@given(data=st.data())
def test_every_path_in_a_config_answers_every_path_shape(
    plain_argv_module: None, capsys: pytest.CaptureFixture[str], key: str, data: st.DataObject
) -> None:
    """Property: a path of a hostile shape written in a ``--config`` file is refused by the path gate as the same
    path given as a flag is: exit 2, one line naming the key, nothing written, never a traceback or a hang."""
    kind = data.draw(st.sampled_from(GATED_SHAPES), label="shape")
    command, template = CONFIG_PATH_KEYS[key]
    with tempfile.TemporaryDirectory() as folder:
        tmp = Path(folder)
        path = _shape(kind, tmp, "out-x" if key.endswith("output_dir") else "x")
        config = tmp / "hostile.yaml"  # a JSON string is a YAML one: a NUL byte or undecodable bytes as escapes
        config.write_text(template.format(path=json.dumps(path)))
        argv = [command, "--config", str(REPO / "configs" / "demo.yaml"), "--config", str(config)]
        argv += [f"--trainer.default_root_dir={tmp / 'run'}", "--trainer.logger=false", "--trainer.max_steps=1"]
        if key != "data.root":
            argv += [f"--data.root={tmp / 'no-set'}"]  # never a default set generated in the working folder
        assert _contract(capsys, argv, [config], says=f"{key} ") == 2, (key, kind)
        assert not {"run", "no-set"} & {p.name for p in tmp.iterdir()}, (key, kind)


@pytest.mark.parametrize("kind", ["long-name", "nul-byte", "link-loop"])
def test_a_path_in_a_checkpoints_config_goes_through_the_gate(
    plain_argv_module: None, capsys: pytest.CaptureFixture[str], tmp_path: Path, kind: str
) -> None:
    """The config a checkpoint carries (``predict --ckpt_path CKPT`` without ``--config``) is read through the same
    gate: a hostile ``data.root`` in it is one line naming the key, before anything else is read or written."""
    import yaml

    from stamlane.training.lightning_cli import CONFIG_KEY

    content = torch.load(REPO / "src/stamlane/weights/stam4-synthetic.ckpt", map_location="cpu", weights_only=True)
    stored = yaml.safe_load(content[CONFIG_KEY])
    stored["data"]["root"] = _shape(kind, tmp_path, "x")
    content[CONFIG_KEY] = yaml.safe_dump(stored)
    ckpt = tmp_path / "hostile.ckpt"
    torch.save(content, ckpt)
    argv = ["validate", "--ckpt_path", str(ckpt), f"--trainer.default_root_dir={tmp_path / 'run'}"]
    assert _contract(capsys, argv, [ckpt], says="data.root ") == 2
    assert not (tmp_path / "run").exists()
