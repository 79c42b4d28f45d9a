"""A fuzzing harness per ``stamlane-eval`` subcommand (tusimple, culane / apollo, video, video --temporal).

Each example builds a small valid input, applies ONE hostile edit drawn by hypothesis from the categories of the
hostile-input passes (wrong types, strings or booleans for numbers, nan / inf / 1e400, duplicates, huge sizes,
links leading outside the folders, FIFOs, outputs equal to inputs) and checks the contract:

- exit 0 with numbers that are rates (and, where the official tool's reading is known, the right numbers), or
  exit 2 with exactly one line on stderr, nothing on stdout, never a traceback;
- no input changed (hashes before and after), nothing of a file outside the folders quoted;
- bounded time (an alarm; a FIFO opened blocking would hang here).

Deterministic (``derandomize=True``) and fast (a few seconds per subcommand).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import signal
import stat
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from stamlane_eval.cli import main
from stamlane_eval.io import MAX_LANES

GOLDEN = Path(__file__).parent / "golden"
SECRET = "the secret 12 34"
SECONDS = 20  # one example: far more than any takes; a blocking open of a FIFO would never return

FUZZ = settings(
    max_examples=30,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)

# values where a number belongs: JSON types that are no number, numbers that are no pixel
HOSTILE_VALUES = ["1", "", True, False, None, [], {}, [1, 2], float("nan"), float("inf"), -float("inf"), 10**400, 1e300]
# tokens in a CULane text line (whitespace separated): what the C++ ``>>`` fails on, or reads
HOSTILE_TOKENS = ["nan", "-nan", "inf", "1e400", "abc", "1_0", "0x10", "1e", "-", ".", "+5", "1.e2", "-0", "1e-400"]
_PREFIX_READ = {"0x10": "0", "1_0": "1"}  # tokens of HOSTILE_TOKENS whose first characters are a whole number
_PLAIN = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")


# ------------------------------------------------------------------------------------------------ the contract
def _snapshot(paths: list[Path]) -> dict[str, str]:
    """A hash of every file under the given paths (links by their target's name, special files by kind)."""
    out: dict[str, str] = {}

    def one(p: Path) -> None:
        mode = os.lstat(p).st_mode
        if stat.S_ISLNK(mode):
            out[str(p)] = "link:" + os.readlink(p)
        elif stat.S_ISREG(mode):
            out[str(p)] = hashlib.sha256(p.read_bytes()).hexdigest()
        elif stat.S_ISDIR(mode):
            for child in sorted(p.iterdir()):
                one(child)
        else:
            out[str(p)] = "special"

    for path in paths:
        if os.path.lexists(path):
            one(path)
    return out


def _alarm(*_: object) -> None:
    raise TimeoutError("stamlane-eval blocked or ran past the time bound")


def _run(capsys: pytest.CaptureFixture[str], argv: list[object], watched: list[Path]) -> tuple[int, str, str]:
    """Run the command and check what holds for every input: exit 0 or one line + exit 2, inputs unchanged,
    nothing of the outside secret quoted, bounded time."""
    before = _snapshot(watched)
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(SECONDS)
    start = time.monotonic()
    try:
        code = main([str(a) for a in argv])
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    out, err = capsys.readouterr()
    assert time.monotonic() - start < SECONDS
    assert "Traceback" not in err and SECRET not in out + err, err
    if code == 0:
        assert out and len(err.strip().splitlines()) <= 1, err  # at most one warning line
    else:
        assert code == 2 and out == "" and len(err.strip().splitlines()) == 1, (code, out, err)
    assert _snapshot(watched) == before, "an input changed"
    return code, out, err


def _secret(folder: Path) -> Path:
    path = folder / "outside" / "secret.txt"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(SECRET + "\n")
    return path


def _special(data: st.DataObject, path: Path, secret: Path, kinds: tuple[str, ...] = ("fifo", "link")) -> str:
    """Replace a file by a FIFO or by a link to a file outside the folders given."""
    kind = data.draw(st.sampled_from(kinds))
    path.unlink()
    if kind == "fifo":
        os.mkfifo(path)
    else:
        path.symlink_to(secret)
    return kind


def _edit_json(value: object, data: st.DataObject, accept: Callable[[list], bool]) -> object:
    """``value`` with one number (found at a path ``accept`` takes) replaced by a hostile value."""
    paths = list(_number_paths(value, []))
    paths = [p for p in paths if accept(p)]
    if not paths:
        return value
    where = data.draw(st.sampled_from(paths))
    new = data.draw(st.sampled_from(HOSTILE_VALUES))
    node = value
    for key in where[:-1]:
        node = node[key]
    node[where[-1]] = new
    return value


def _number_paths(value: object, path: list) -> Iterator[list]:
    if isinstance(value, dict):
        for k, v in value.items():
            yield from _number_paths(v, [*path, k])
    elif isinstance(value, list):
        for i, v in enumerate(value):
            yield from _number_paths(v, [*path, i])
    elif type(value) in (int, float):
        yield path


def _dumps(value: object) -> str:
    return json.dumps(value)  # NaN / Infinity as lane.py's ujson and Python read them; 10**400 as digits


def _rates(d: dict, keys: tuple[str, ...]) -> None:
    for k in keys:
        assert 0.0 <= d[k] <= 1.0 + 1e-9, (k, d)


# ------------------------------------------------------------------------------------------------- tusimple
_TS = [json.loads(x) for x in (GOLDEN / "tusimple_pred.json").read_text().splitlines()[:4]]
_TS_GT = {g["raw_file"]: g for g in map(json.loads, (GOLDEN / "tusimple_gt.json").read_text().splitlines())}


@FUZZ
@given(st.data(), st.sampled_from(["value", "duplicate", "respelled", "huge", "special", "output", "temporary"]))
def test_fuzz_tusimple(
    tmp_path_factory: pytest.TempPathFactory, capsys: pytest.CaptureFixture[str], data: st.DataObject, how: str
) -> None:
    folder = tmp_path_factory.mktemp("fz_ts")
    secret = _secret(folder)
    preds = json.loads(json.dumps(_TS))
    gts = [json.loads(json.dumps(_TS_GT[p["raw_file"]])) for p in preds]
    pred, gt = folder / "pred.json", folder / "gt.json"
    if how == "temporary":  # an input named as a fixed temporary name of the output would be
        pred = folder / ".per.jsonl.tmp"
    side = data.draw(st.sampled_from(["pred", "gt"]))
    if how == "value":
        recs = preds if side == "pred" else gts
        k = data.draw(st.integers(0, len(recs) - 1))
        _edit_json(recs[k], data, lambda p: True)
    elif how == "duplicate":
        recs = preds if side == "pred" else gts
        recs.append(recs[data.draw(st.integers(0, len(recs) - 1))])
    elif how == "respelled":  # one image named again in another spelling: the same image (normalised once)
        recs = preds if side == "pred" else gts
        rec = recs[data.draw(st.integers(0, len(recs) - 1))]
        folder_name, _, name = rec["raw_file"].rpartition("/")
        how_spelled = data.draw(st.sampled_from(["{}/./{}", "{}//{}", "{}/x/../{}", "./{}/{}"]))
        recs.append({**rec, "raw_file": how_spelled.format(folder_name, name)})
    elif how == "huge":  # past the documented budget: more than MAX_COMPARED_CELLS (lane, lane, row) in one image
        rows, lanes = data.draw(st.sampled_from([(16_385, 128), (65_537, 64)]))  # 128 * 128 * 16_385 > 2**28
        gts[0]["h_samples"] = list(range(rows))
        gts[0]["lanes"] = [[5] * rows] * lanes
        preds[0]["lanes"] = [[5] * rows] * lanes
    pred.write_text("".join(_dumps(r) + "\n" for r in preds))
    gt.write_text("".join(_dumps(r) + "\n" for r in gts))
    argv: list[object] = ["tusimple", pred, gt, "--json"]
    if how == "special":
        _special(data, pred if side == "pred" else gt, secret, ("fifo",))  # a file named by the user is followed
    if how == "output":
        (folder / "link.jsonl").symlink_to(gt)
        argv += ["--per-image", data.draw(st.sampled_from([pred, gt, folder / "link.jsonl", folder]))]
    watched = [folder]
    if how == "temporary":
        argv += ["--per-image", folder / "per.jsonl"]
        watched = [pred, gt, secret]
    code, out, _ = _run(capsys, argv, watched)
    if how == "temporary":
        assert code == 0 and sorted(q.name for q in folder.iterdir()) == [
            ".per.jsonl.tmp",
            "gt.json",
            "outside",
            "per.jsonl",
        ]
    if how in ("special", "output", "huge", "respelled") or (how == "duplicate" and side == "gt"):
        assert code == 2  # a respelled prediction names no image of the ground truth: lane.py's KeyError
    if code == 0:
        _rates(json.loads(out), ("accuracy",))


# ---------------------------------------------------------------------------------------------- culane / apollo
_CU_PRED = ["100 580 130 500 160 420 190 340\n", "600 580 560 500 520 420\n"]
_CU_GT = ["102 580 131 500 161 420 190 340\n", "598 580 561 500 519 420\n"]


def _cpp_reading(line: str) -> str:
    """An independent model of the C++ tool's ``while (ss >> x >> y)`` for whitespace-separated tokens: the plain
    finite numbers up to the first other token, pairs only."""
    vals = []
    for tok in line.split():
        if tok in _PREFIX_READ:  # >> reads the number the token starts with, the next read fails
            vals.append(_PREFIX_READ[tok])
            break
        if not _PLAIN.fullmatch(tok) or float(tok) in (float("inf"), -float("inf")):
            break
        vals.append(tok)
    return " ".join(vals[: len(vals) // 2 * 2]) + "\n"


def _culane_tree(folder: Path, pred_lines: list[list[str]], gt_lines: list[list[str]]) -> tuple[Path, Path]:
    for i, (p, g) in enumerate(zip(pred_lines, gt_lines, strict=True)):
        for sub, lines in (("pred", p), ("gt", g)):
            (folder / sub / "d").mkdir(parents=True, exist_ok=True)
            (folder / sub / "d" / f"{i}.lines.txt").write_text("".join(lines))
    return folder / "pred", folder / "gt"


@FUZZ
@given(
    st.data(),
    st.sampled_from(["token", "duplicate", "huge", "special", "output"]),
    st.sampled_from(["culane", "apollo"]),
)
def test_fuzz_culane(
    tmp_path_factory: pytest.TempPathFactory,
    capsys: pytest.CaptureFixture[str],
    data: st.DataObject,
    how: str,
    command: str,
) -> None:
    folder = tmp_path_factory.mktemp("fz_cu")
    secret = _secret(folder)
    preds = [list(_CU_PRED) for _ in range(3)]
    gts = [list(_CU_GT) for _ in range(3)]
    listing = folder / "list.txt"
    entries = [f"/d/{i}.jpg" for i in range(3)]
    extra: list[object] = ["--size", "1640x590"]
    side = data.draw(st.sampled_from(["pred", "gt"]))
    if how == "token":  # a hostile token in one line (a prediction's is read as the C++ tool reads it)
        lines = preds if side == "pred" else gts
        i, k = data.draw(st.integers(0, 2)), data.draw(st.integers(0, 1))
        words = lines[i][k].split()
        at = data.draw(st.integers(0, len(words)))
        words.insert(at, data.draw(st.sampled_from(HOSTILE_TOKENS)))
        lines[i][k] = " ".join(words) + "\n"
    elif how == "duplicate":
        entries.append(data.draw(st.sampled_from(["/d/0.jpg", "d/0.png", "/d/0.lines.txt"])))
    elif how == "huge":
        what = data.draw(st.sampled_from(["size", "points", "lanes", "too many lanes"]))
        if what == "size":  # lanes across a 16384 x 16384 frame: past the canvas budget
            lane = "".join(f"{100 + 0.9 * y:.1f} {y} " for y in range(0, 16000, 400)) + "\n"
            preds, gts = [[lane] * 6 for _ in range(3)], [[lane] * 6 for _ in range(3)]
            extra = ["--size", "16384x16384"]
        elif what == "points":  # 10,001 points in one lane: the C++ tool scores it, so do we
            preds[0][0] = " ".join(f"{100 + (i % 5)} {580 - i * 0.024:.3f}" for i in range(10_001)) + "\n"
        elif what == "lanes":  # 65 lanes in one image: the C++ tool scores it (#59), so do we
            preds[0] = ["10 500 20 400\n"] * 65
        else:  # past the time budget, MAX_LANES
            preds[0] = ["10 500 20 400\n"] * (MAX_LANES + 1)
    listing.write_text("".join(e + "\n" for e in entries))
    pred, gt = _culane_tree(folder, preds, gts)
    argv: list[object] = [command, pred, gt, "--list", listing, "--json", *extra]
    if how == "special":
        target = data.draw(st.sampled_from([pred / "d" / "1.lines.txt", gt / "d" / "1.lines.txt", listing]))
        _special(data, target, secret, ("fifo",) if target == listing else ("fifo", "link"))
    if how == "output":
        (folder / "link.jsonl").symlink_to(listing)
        out = data.draw(st.sampled_from([listing, folder / "link.jsonl", pred / "d" / "0.lines.txt", gt, gt / "n"]))
        argv += ["--per-image", out]
    code, out, err = _run(capsys, argv, [folder])
    if how in ("output", "duplicate", "special"):
        assert code == 2, err
    if how == "huge":
        assert code == (0 if what in ("points", "lanes") else 2), err
    if how == "token" and side == "pred":  # the right numbers: those of the line as the C++ tool reads it
        assert code == 0, err
        clean = [[_cpp_reading(x) for x in lines] for lines in preds]
        want_pred, _ = _culane_tree(tmp_path_factory.mktemp("fz_cu_want"), clean, gts)
        want = main([command, str(want_pred), str(gt), "--list", str(listing), "--json", *map(str, extra)])
        assert want == 0 and json.loads(capsys.readouterr().out) == json.loads(out)
    if code == 0:
        res = json.loads(out)
        for t in ("0.3", "0.5"):
            _rates(res[t], ("precision", "recall", "f1"))


# ------------------------------------------------------------------------------------------- video, --temporal
_VIL_LANES = [[[100, 350], [150, 250], [200, 150]], [[500, 350], [460, 250], [420, 150]]]


def _vil_doc() -> dict:
    lanes = [{"lane_id": k + 1, "points": json.loads(json.dumps(p))} for k, p in enumerate(_VIL_LANES)]
    return {"info": {"width": 640, "height": 360}, "annotations": {"lane": lanes}}


def _video_case(folder: Path, data: st.DataObject, how: str, secret: Path, temporal: bool) -> list[object]:
    """A VIL-100 layout of 3 frames with one hostile edit (``how``); returns the command line."""
    docs = {f"{i:05d}.jpg.json": _vil_doc() for i in range(3)}
    pred_text = {
        f"{i:05d}": "".join(" ".join(f"{x} {y}" for x, y in lane) + "\n" for lane in _VIL_LANES) for i in range(3)
    }
    extra: list[object] = []
    sizes = folder / "sizes.json"
    sizes.write_text('{"v": "640x360"}')
    listing = folder / "list.txt"
    entries = [f"/JPEGImages/v/{i:05d}.jpg" for i in range(3)]
    if how == "value":
        name = data.draw(st.sampled_from(sorted(docs)))
        _edit_json(docs[name], data, lambda p: True)
    elif how == "token":
        frame = data.draw(st.sampled_from(sorted(pred_text)))
        words = pred_text[frame].split(" ")
        at = data.draw(st.integers(0, len(words)))
        words.insert(at, data.draw(st.sampled_from(HOSTILE_TOKENS)))
        pred_text[frame] = " ".join(words)
    elif how == "duplicate":
        if data.draw(st.sampled_from(["label", "list"])) == "label":
            docs["00001.png.json"] = _vil_doc()
        else:
            again = ["v/00001.jpg", "/JPEGImages/v/00000.png", "/JPEGImages/v/./00001.jpg", "v//00002.jpg"]
            entries.append(data.draw(st.sampled_from(again)))
    elif how == "huge":
        what = data.draw(st.sampled_from(["size", "info", "sizes"]))
        if what == "size":
            lane = [[100 + 0.9 * y, y] for y in range(0, 16000, 400)]
            for doc in docs.values():
                doc["annotations"]["lane"] = [{"lane_id": k, "points": lane} for k in range(6)]
            pred_text = {f: "".join(" ".join(f"{x} {y}" for x, y in lane) + "\n" for _ in range(6)) for f in pred_text}
            extra = ["--size", "16384x16384"]
        elif what == "info":
            docs["00001.jpg.json"]["info"]["width"] = data.draw(st.sampled_from([10**6, 0, -5, 16385]))
        else:
            sizes.write_text(json.dumps({"v": data.draw(st.sampled_from(["16385x10", "0x5", 640, True, "1e9x1"]))}))
            extra = ["--sizes", sizes]
    elif how == "far" and temporal:  # RVLD's script scores predictions far outside the image
        x = data.draw(st.sampled_from([150_000, -150_000]))
        pred_text["00001"] = f"{x} 350 {x + 10} 250 {x + 20} 150\n" + pred_text["00001"]
    listing.write_text("".join(e + "\n" for e in entries))
    for name, doc in docs.items():
        (folder / "gt" / "Json" / "v").mkdir(parents=True, exist_ok=True)
        (folder / "gt" / "Json" / "v" / name).write_text(_dumps(doc))
    for frame, text in pred_text.items():
        (folder / "pred" / "v").mkdir(parents=True, exist_ok=True)
        (folder / "pred" / "v" / f"{frame}.lines.txt").write_text(text)
    argv: list[object] = ["video", folder / "pred", folder / "gt", "--json", "--list", listing, *extra]
    argv += ["--temporal"] if temporal else []
    if how == "special":
        target = data.draw(
            st.sampled_from(
                [folder / "pred" / "v" / "00001.lines.txt", folder / "gt" / "Json" / "v" / "00001.jpg.json"]
            )
        )
        _special(data, target, secret)
    if how == "output":
        if "--sizes" not in argv:
            argv += ["--sizes", sizes]
        (folder / "link.jsonl").symlink_to(sizes)
        out = data.draw(st.sampled_from([sizes, folder / "link.jsonl", listing, folder / "pred" / "x.jsonl"]))
        argv += ["--per-sequence", out]
    return argv


def _check_video(code: int, out: str, temporal: bool) -> None:
    if code != 0:
        return
    res = json.loads(out)
    if temporal:
        for t in ("0.5", "0.8"):
            c = res[t]
            assert min(c["Ns"], c["Nj"], c["Nm"]) >= 0 and abs(c["Rs"] + c["Rj"] + c["Rm"] - 1) < 1e-9, c
    else:
        _rates(res, ("miou", "switch_rate", "flicker_rate"))
        for t in ("0.5", "0.8"):
            _rates(res[t], ("precision", "recall", "f1"))


@FUZZ
@given(st.data(), st.sampled_from(["value", "token", "duplicate", "huge", "special", "output"]))
def test_fuzz_video(
    tmp_path_factory: pytest.TempPathFactory, capsys: pytest.CaptureFixture[str], data: st.DataObject, how: str
) -> None:
    folder = tmp_path_factory.mktemp("fz_vd")
    argv = _video_case(folder, data, how, _secret(folder), temporal=False)
    code, out, err = _run(capsys, argv, [folder])
    if how in ("duplicate", "huge", "special", "output"):
        assert code == 2, err
    if how == "token":
        assert code == 0, err
    _check_video(code, out, temporal=False)


@FUZZ
@given(st.data(), st.sampled_from(["value", "token", "duplicate", "huge", "special", "output", "far"]))
def test_fuzz_video_temporal(
    tmp_path_factory: pytest.TempPathFactory, capsys: pytest.CaptureFixture[str], data: st.DataObject, how: str
) -> None:
    folder = tmp_path_factory.mktemp("fz_tp")
    argv = _video_case(folder, data, how, _secret(folder), temporal=True)
    code, out, err = _run(capsys, argv, [folder])
    if how in ("duplicate", "huge", "special", "output"):
        assert code == 2, err
    if how == "far":
        assert code == 0, err
        base = _video_case(tmp_path_factory.mktemp("fz_tp_base"), data, "none", folder, temporal=True)
        assert main([str(a) for a in base]) == 0
        want = json.loads(capsys.readouterr().out)
        got = json.loads(out)
        # the far lane draws nothing: the frame's counts are those without it
        assert {t: got[t] for t in ("0.5", "0.8")} == {t: want[t] for t in ("0.5", "0.8")}
    _check_video(code, out, temporal=True)


# ------------------------------------------------------------------------------------------ every path option
_PATH_SHAPES = ("long-name", "long-component", "long-path", "fifo", "device", "sparse", "loop", "dangling", "dots")
_PATH_SHAPES += ("not-utf8", "nul-byte", "under-a-file")


def _path_shape(kind: str, folder: Path, output: bool) -> str:
    """A path of the shape ``kind`` in ``folder`` (an output's device: a link to it, never the node itself)."""
    if kind == "long-name":
        return str(folder / ("n" * 300))
    if kind == "long-component":
        return str(folder / ("c" * 256) / "x.json")
    if kind == "long-path":
        return str(folder.joinpath(*["p" * 200] * 22, "x.json"))
    if kind == "fifo":
        os.mkfifo(folder / "fifo")
        return str(folder / "fifo")
    if kind == "device":
        if output:
            (folder / "device").symlink_to("/dev/zero")
            return str(folder / "device")
        return "/dev/zero"
    if kind == "sparse":
        with open(folder / "sparse.json", "wb") as file:
            file.truncate(2 << 30)
        return str(folder / "sparse.json")
    if kind == "loop":
        (folder / "a").symlink_to(folder / "b")
        (folder / "b").symlink_to(folder / "a")
        return str(folder / "a")
    if kind == "dangling":
        (folder / "dangling").symlink_to(folder / "nothing")
        return str(folder / "dangling")
    if kind == "dots":
        return f"{folder}/./x/..//missing.json"
    if kind == "not-utf8":
        os.makedirs(os.fsencode(folder) + b"/\xff\xfe")
        return os.fsdecode(os.fsencode(folder) + b"/\xff\xfe")
    if kind == "nul-byte":
        return f"{folder}/a\x00b"
    (folder / "file").write_text("x")
    return str(folder / "file" / "x.json")


_PATH_COMMANDS = {
    "tusimple-pred": ["tusimple", "{path}", "{gt}"],
    "tusimple-gt": ["tusimple", "{pred}", "{path}"],
    "tusimple-per-image": ["tusimple", "{pred}", "{gt}", "--per-image", "{path}"],
    "culane": ["culane", "{path}", "{path}"],
    "video-pred": ["video", "{path}", "{gt}", "--size", "640x360"],
    "video-gt": ["video", "{pred}", "{path}", "--size", "640x360"],
    "video-per-sequence": ["video", "{pred}", "{gt}", "--size", "640x360", "--per-sequence", "{path}"],
}


@pytest.mark.parametrize("command", sorted(_PATH_COMMANDS))
@settings(max_examples=6, deadline=None, derandomize=True, database=None, suppress_health_check=list(HealthCheck))
@given(data=st.data())
def test_every_path_option_answers_every_path_shape(
    tmp_path_factory: pytest.TempPathFactory, capsys: pytest.CaptureFixture[str], command: str, data: st.DataObject
) -> None:
    """Property: a path of any shape given to any path option of ``stamlane-eval`` is one line and exit 2 (an output
    that is a regular file, or a link to nothing, is written: exit 0), never a traceback or a hang; a device or a
    FIFO given as an output is never replaced."""
    folder = tmp_path_factory.mktemp("fz_path")
    output = command.endswith(("per-image", "per-sequence"))
    kind = data.draw(st.sampled_from(_PATH_SHAPES), label="shape")
    pred, gt = folder / "pred.json", folder / "gt.json"
    gt.write_text(_dumps({"raw_file": "clips/c/1.jpg", "lanes": [[100, 101, 102]], "h_samples": [300, 310, 320]}))
    pred.write_text(_dumps({**json.loads(gt.read_text()), "run_time": 1}))
    path = _path_shape(kind, folder, output)
    argv = [a.format(path=path, pred=pred, gt=gt) for a in _PATH_COMMANDS[command]]
    code, _, _ = _run(capsys, argv, [pred, gt])
    assert code == 2 or (output and kind in ("sparse", "dangling", "dots")), (command, kind)
    if kind == "device" and output:
        assert (folder / "device").is_symlink() and os.stat("/dev/zero").st_rdev == os.makedev(1, 5)
