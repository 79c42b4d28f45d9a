"""The path gate (`stamlane.safety.paths`): every shape of path answered, never an exception."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stamlane.safety.paths import (
    MAX_CONFIG_BYTES,
    PathError,
    check_arguments,
    check_command_files,
    check_config_paths,
    inspect_path,
    require,
    shown,
)


@pytest.fixture
def shapes(tmp_path: Path) -> dict[str, Path | str]:
    (tmp_path / "file").write_text("x")
    (tmp_path / "folder").mkdir()
    os.mkfifo(tmp_path / "fifo")
    (tmp_path / "link").symlink_to(tmp_path / "file")
    (tmp_path / "dangling").symlink_to(tmp_path / "nothing")
    (tmp_path / "loop-a").symlink_to(tmp_path / "loop-b")
    (tmp_path / "loop-b").symlink_to(tmp_path / "loop-a")
    with open(tmp_path / "sparse", "wb") as file:
        file.truncate(2 << 30)
    return {
        "file": tmp_path / "file",
        "folder": tmp_path / "folder",
        "fifo": tmp_path / "fifo",
        "device": "/dev/zero",
        "link": tmp_path / "link",
        "dangling": tmp_path / "dangling",
        "loop": tmp_path / "loop-a",
        "sparse": tmp_path / "sparse",
        "long-name": tmp_path / ("n" * 300),
        "long-path": str(tmp_path) + "/p" * 3000,
        "nul": f"{tmp_path}/a\x00b",
        "not-utf8": os.fsdecode(os.fsencode(tmp_path) + b"/\xff"),
        "under-a-file": tmp_path / "file" / "x",
        "dots": f"{tmp_path}/./folder/../file",
    }


EXPECTED = {
    "file": ("file", None),
    "folder": ("folder", None),
    "fifo": ("fifo", None),
    "device": ("device", None),
    "link": ("file", None),
    "dangling": ("missing", None),
    "loop": ("unusable", "is a loop of links"),
    "sparse": ("file", None),
    "long-name": ("unusable", "over the file system's limit of 255"),
    "long-path": ("unusable", "over the file system's limit of 4096"),
    "nul": ("unusable", "NUL byte"),
    "not-utf8": ("unusable", "not UTF-8"),
    "under-a-file": ("missing", None),
    "dots": ("file", None),
}


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_every_shape_is_answered(shapes: dict[str, Path | str], name: str) -> None:
    info = inspect_path(shapes[name])
    kind, problem = EXPECTED[name]
    assert info.kind == kind and (problem is None) == (info.problem is None), info
    assert problem is None or problem in info.problem
    assert info.link == (name in ("link", "dangling", "loop"))
    assert info.size == ({"file": 1, "link": 1, "dots": 1, "sparse": 2 << 30}.get(name))
    assert "\n" not in info.shown and len(info.shown) < 340


def test_require_refuses_in_one_line(shapes: dict[str, Path | str], tmp_path: Path) -> None:
    assert require(shapes["file"], "config").kind == "file"
    assert require(shapes["folder"], "--source", ("file", "folder")).kind == "folder"
    for name, words in [
        ("fifo", "is a FIFO, not a file"),
        ("device", "is a device, not a file"),
        ("folder", "is a folder, not a file"),
        ("dangling", "does not exist (a link to nothing)"),
        ("long-name", "over the file system's limit"),
    ]:
        with pytest.raises(PathError, match=words.replace("(", r"\(").replace(")", r"\)")):
            require(shapes[name], "config")
    with pytest.raises(PathError, match="over the limit of 16 MiB"):
        require(shapes["sparse"], "config", limit=MAX_CONFIG_BYTES)
    with pytest.raises(PathError, match="lies outside"):
        require(shapes["file"], "label", roots=[shapes["folder"]])
    assert require(shapes["link"], "label", roots=[tmp_path]).root == tmp_path
    assert require(tmp_path / "missing", "x", missing_ok=True).kind == "missing"


def test_command_files_and_arguments(shapes: dict[str, Path | str]) -> None:
    check_command_files(["--config", str(shapes["file"]), "--source", str(shapes["folder"]), "--ckpt_path", "last"])
    for args in (["-c", str(shapes["fifo"])], [f"--ckpt_path={shapes['device']}"], ["--config", str(shapes["sparse"])]):
        with pytest.raises(PathError):
            check_command_files(args)
    check_arguments(["--out", str(shapes["fifo"]), "--n=3", "word", str(shapes["dots"])])  # what a path IS: later
    for arg in ("long-name", "loop", "nul", "not-utf8"):
        with pytest.raises(PathError, match=r"^argument "):
            check_arguments(["--out", str(shapes[arg])])
        with pytest.raises(PathError, match=r"^argument "):
            check_arguments([f"--out={shapes[arg]}"])


def test_config_paths(shapes: dict[str, Path | str]) -> None:
    """The path-valued options of a parsed config (nested mappings; jsonargparse's Namespace has the same ``get``)
    go through `require`: the key named, a missing path or a checkpoint name passed to its reader."""
    good = {
        "data": {"root": str(shapes["folder"]), "clip": {"cache_dir": str(shapes["dangling"])}},
        "model": {"init_weights": str(shapes["link"]), "encoder": {"class_path": "x", "init_args": {"weights": None}}},
        "predictions": {"output_dir": str(shapes["dots"]).replace("/file", "/new")},
        "ckpt_path": "last",
        "source": str(shapes["file"]),
    }
    check_config_paths(good)
    check_config_paths({"data": [1, 2], "model": "a string", "ckpt_path": 3})  # no mapping, no path: not the gate's
    hostile = {
        ("data", "root"): ("file", "is a file, not a folder"),
        ("model", "init_weights"): ("fifo", "is a FIFO, not a file"),
        ("model", "encoder", "init_args", "weights"): ("device", "is a device"),
        ("predictions", "output_dir"): ("loop", "is a loop of links"),
        ("ckpt_path",): ("long-name", "over the file system's limit"),
        ("source",): ("nul", "holds a NUL byte"),
    }
    for keys, (shape, problem) in hostile.items():
        config: dict = {}
        inner = config
        for key in keys[:-1]:
            inner = inner.setdefault(key, {})
        inner[keys[-1]] = str(shapes[shape])
        with pytest.raises(PathError, match=rf"^{'.'.join(keys)} .*{problem}"):
            check_config_paths(config)


@settings(max_examples=200, deadline=None, derandomize=True, database=None)
@given(st.one_of(st.text(max_size=600), st.binary(max_size=600).map(os.fsdecode)))
def test_the_gate_never_raises(path: str) -> None:
    """Property: any string (any bytes, as the shell hands them over) is answered, and shown on one line."""
    info = inspect_path(path)
    assert info.kind in ("file", "folder", "fifo", "device", "socket", "missing", "unusable")
    assert "\n" not in shown(path) and "\n" not in info.shown


def test_a_long_yaml_value_is_no_path() -> None:
    """``--trainer.callbacks=[...]`` or ``--data.predict_labels=[...]`` may be long: values, not paths."""
    labels = "[" + ",".join(f"split-{i}.json" for i in range(40)) + "]"
    check_arguments([f"--data.predict_labels={labels}", "--config", "{" + '"a": 1, ' * 60 + "}"])
    with pytest.raises(PathError):
        check_arguments([f"--data.root={'r' * 300}"])
