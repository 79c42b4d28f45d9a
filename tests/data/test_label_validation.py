"""Typed-bad labels: the datasets and stamlane-eval refuse the same records for the same reason (one typed check,
``stamlane_eval.io.tusimple_record_error``); ``on_error: skip`` drops them and counts them."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from stamlane_eval.cli import main as eval_main

from stamlane.data import DataError, TuSimpleClips
from stamlane.data.options import ClipOptions
from tests.data.conftest import H, W

SIZE = (32, 48)
RAW = "clips/0313-1/100/20.jpg"
ROWS = list(range(20, 64, 10))

HOSTILE = [
    ({"lanes": ["abc"]}, "lane 0 must be a list of numbers"),
    ({"lanes": [[60, "65", 70, 75, 80]]}, "lane 0 must be a list of numbers, got '65'"),
    ({"lanes": [[60, True, 70, 75, 80]]}, "a boolean"),
    ({"lanes": [[60, 1e12, 70, 75, 80]]}, "lane 0 has 1000000000000.0: not a pixel coordinate"),
    ({"lanes": [[60, 1e400, 70, 75, 80]]}, "lane 0 has inf: not a pixel coordinate"),  # json.dumps: Infinity
    ({"lanes": [[60, 65, 70, 75]]}, "lane 0 has 4 x values, h_samples has 5"),
    ({"lanes": [], "h_samples": []}, "h_samples is empty"),
    ({"h_samples": {"a": 1}}, "h_samples must be a list of numbers"),
    ({"raw_file": 7}, "raw_file must be a non-empty string"),
    ({"lanes": {"0": [1]}}, "lanes must be a list of lists"),
]


def _record(**changes: object) -> dict:
    return {"raw_file": RAW, "lanes": [[60, 65, 70, 75, 80]], "h_samples": ROWS} | changes


@pytest.mark.parametrize(("changes", "message"), HOSTILE, ids=[m for _, m in HOSTILE])
def test_a_typed_bad_label_is_refused_by_the_dataset_and_the_evaluator(
    tusimple_root: Path, tmp_path: Path, capsys: pytest.CaptureFixture, changes: dict, message: str
) -> None:
    good = (tusimple_root / "label_data.json").read_text().splitlines()[1]  # clip 200
    bad = json.dumps(_record(**changes))
    (tusimple_root / "bad.json").write_text(bad + "\n" + good + "\n")
    with pytest.raises(DataError, match="bad.json: line 1: " + message.replace("(", r"\(")):
        TuSimpleClips(tusimple_root, "bad.json", clip=ClipOptions(num_frames=1, image_size=SIZE, align="none"))
    with pytest.warns(UserWarning, match="skipped"):
        skip = TuSimpleClips(
            tusimple_root, "bad.json", clip=ClipOptions(num_frames=1, image_size=SIZE, align="none"), on_error="skip"
        )
    assert len(skip) == 1 and len(skip.skipped) == 1 and message.split(",")[0][:12] in skip.skipped[0]
    # the same file as ground truth for stamlane-eval: one line, exit 2, no traceback
    pred = tmp_path / "pred.json"
    pred.write_text(json.dumps({"raw_file": RAW, "lanes": [], "run_time": 1}) + "\n")
    gt_file = str(tusimple_root / "bad.json")
    assert eval_main(["tusimple", str(pred), gt_file]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err and "bad.json" in err


def test_duplicates_and_far_points_are_refused(tusimple_root: Path) -> None:
    label = tusimple_root / "label_data.json"
    first, second = label.read_text().splitlines()
    label.write_text("\n".join([first, second, first]) + "\n")
    with pytest.raises(
        DataError, match=r"label_data.json:3: raw_file .* again \(first at .*label_data.json:1\): two labels"
    ):
        TuSimpleClips(tusimple_root, "label_data.json", clip=ClipOptions(num_frames=1, image_size=SIZE, align="none"))
    far = _record(lanes=[[60, 65, 70, 75, 40 * W]])  # inside MAX_COORDINATE, far outside this small image
    label.write_text(json.dumps(far) + "\n" + second + "\n")
    ds = TuSimpleClips(tusimple_root, "label_data.json", clip=ClipOptions(num_frames=1, image_size=SIZE, align="none"))
    with pytest.raises(DataError, match=rf"lane 0 has the point \({40 * W}, 60\), far outside the {W}x{H} image"):
        ds[0]
    with pytest.warns(UserWarning, match="far outside"):
        skip = TuSimpleClips(
            tusimple_root,
            "label_data.json",
            clip=ClipOptions(num_frames=1, image_size=SIZE, align="none"),
            on_error="skip",
        )
        sample = skip[0]
    assert sample["meta"]["raw_file"].endswith("200/20.jpg") and len(skip.skipped) == 1


def test_one_json_document_is_not_json_lines(tusimple_root: Path) -> None:
    (tusimple_root / "pretty.json").write_text(json.dumps(_record(), indent=2))
    with pytest.raises(
        DataError, match=r"one JSON document over .* lines; TuSimple files hold one JSON object per line"
    ):
        TuSimpleClips(tusimple_root, "pretty.json", clip=ClipOptions(num_frames=1, image_size=SIZE, align="none"))


def test_the_datamodule_reports_how_many_samples_it_skipped(tusimple_root: Path) -> None:
    from stamlane.data.datamodule import ClipDataModule
    from stamlane.data.options import ClipOptions

    good = (tusimple_root / "label_data.json").read_text().splitlines()[1]
    (tusimple_root / "bad.json").write_text(json.dumps(_record(lanes=["abc"])) + "\n" + good + "\n")
    clip = ClipOptions(num_frames=1, image_size=SIZE)
    data = ClipDataModule(root=str(tusimple_root), clip=clip, test_labels=["bad.json"], on_error="skip")
    with pytest.warns(UserWarning, match=r"test: skipped 1 of 2 samples with bad data \(on_error: skip\)"):
        data.setup("test")
    assert len(data.datasets["test"]) == 1
