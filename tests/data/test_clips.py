"""Every loader on small files in its layout: shapes, history frames, lanes, meta, and bad data."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from stamlane.data import ApolloClips, CULaneClips, DataError, TuSimpleClips, VIL100Clips
from stamlane.data.clips import frame_order
from stamlane.data.options import ClipOptions
from tests.data.conftest import H, W

SIZE = (32, 48)


def check_sample(s: dict, t: int, fmt: str) -> None:
    assert s["frames"].shape == (t, 3, *SIZE) and s["frames"].dtype == torch.float32
    assert 0.0 <= float(s["frames"].min()) and float(s["frames"].max()) <= 1.0
    assert s["binary"].shape == SIZE and s["binary"].dtype == torch.int64
    assert s["instance"].shape == SIZE and s["instance"].dtype == torch.int64
    assert s["key_from_hist"].shape == (t, 3, 3) and s["key_from_hist"].dtype == torch.float32
    assert torch.equal(s["binary"], (s["instance"] > 0).long())
    assert s["meta"]["format"] == fmt
    assert tuple(s["meta"]["orig_size"]) == (H, W)
    assert np.asarray(s["meta"]["net_from_orig"]).shape == (3, 3)
    assert len(s["meta"]["frame_paths"]) == t


def test_tusimple_history_by_number_lanes_and_meta(tusimple_root: Path):
    ds = TuSimpleClips(
        tusimple_root, "label_data.json", clip=ClipOptions(num_frames=4, stride=1, image_size=SIZE, align="none")
    )
    assert len(ds) == 2
    s = ds[0]
    check_sample(s, 4, "tusimple")
    assert s["meta"]["frame_paths"] == [f"clips/0313-1/100/{n}.jpg" for n in (17, 18, 19, 20)]
    assert s["meta"]["raw_file"] == "clips/0313-1/100/20.jpg"
    assert s["meta"]["h_samples"] == [20, 30, 40, 50, 60]
    # two labelled lanes (the all -2 lane has no points), left to right, -2 dropped, original pixels
    assert len(s["lanes"]) == 2
    np.testing.assert_allclose(s["lanes"][0], [[30, 20], [25, 30], [15, 50], [10, 60]])
    assert s["lanes"][1][:, 0].tolist() == [60, 65, 70, 75, 80]
    assert set(s["instance"].unique().tolist()) == {0, 1, 2}
    # history frames really are the earlier files: frame n was written with grey value 5 n
    blue = s["frames"][:, 0].mean(dim=(1, 2))  # channel 0 = R in the RGB tensor, written grey
    assert torch.all(blue[1:] > blue[:-1])
    ds3 = TuSimpleClips(
        tusimple_root, ["label_data.json"], clip=ClipOptions(num_frames=3, stride=5, image_size=SIZE, align="none")
    )
    assert ds3[1]["meta"]["frame_paths"] == [f"clips/0313-1/200/{n}.jpg" for n in (10, 15, 20)]


def test_culane_list_lines_and_history_by_name(culane_root: Path):
    ds = CULaneClips(
        culane_root, "list/train_gt.txt", clip=ClipOptions(num_frames=2, stride=30, image_size=SIZE, align="none")
    )
    s = ds[0]
    check_sample(s, 2, "culane")
    assert s["meta"]["frame_paths"] == [
        "driver_23_30frame/05151649_0422.MP4/00060.jpg",
        "driver_23_30frame/05151649_0422.MP4/00090.jpg",
    ]
    assert s["meta"]["h_samples"] is None
    np.testing.assert_allclose(s["lanes"][0], [[10.5, 60], [20.5, 40], [30.5, 20]])
    single = CULaneClips(
        culane_root, "list/train_gt.txt", clip=ClipOptions(num_frames=1, image_size=SIZE, align="none")
    )
    check_sample(single[1], 1, "culane")
    # 00000 has no earlier frame: an error, unless the missing history repeats the next frame
    with pytest.raises(DataError, match="history"):
        CULaneClips(
            culane_root, "list/train_gt.txt", clip=ClipOptions(num_frames=4, stride=30, image_size=SIZE, align="none")
        )
    rep = CULaneClips(
        culane_root,
        "list/train_gt.txt",
        clip=ClipOptions(num_frames=4, stride=30, image_size=SIZE, repeat_missing_history=True, align="none"),
    )
    paths = rep[1]["meta"]["frame_paths"]
    assert paths[0] == paths[1] and paths[-1].endswith("00060.jpg")


def test_apollo_sorted_history_and_mirrored_labels(apollo_root: Path):
    ds = ApolloClips(
        apollo_root, "test.txt", clip=ClipOptions(num_frames=3, image_size=SIZE, align="none"), label_dir="labels"
    )
    s = ds[0]
    check_sample(s, 3, "apollo")
    names = [Path(p).name for p in s["meta"]["frame_paths"]]
    assert names == ["170927_063812021_Camera_5.jpg", "170927_063812150_Camera_5.jpg", "170927_063812279_Camera_5.jpg"]
    np.testing.assert_allclose(s["lanes"][0], [[5, 60], [15, 30], [25, 10]])
    with pytest.raises(DataError, match=r"lines\.txt"):  # labels beside the images do not exist
        ApolloClips(apollo_root, "test.txt", clip=ClipOptions(num_frames=1, image_size=SIZE, align="none"))


def test_vil100_json_annotations_every_frame(vil_root: Path):
    ds = VIL100Clips(vil_root, "data/train.txt", clip=ClipOptions(num_frames=3, image_size=SIZE, align="none"))
    assert len(ds) == 2
    s = ds[1]  # ends on frame 3: any labelled frame can be a key frame
    check_sample(s, 3, "vil100")
    assert [Path(p).name for p in s["meta"]["frame_paths"]] == ["00001.jpg", "00002.jpg", "00003.jpg"]
    assert [lane[0, 0] for lane in s["lanes"]] == [10, 70]  # sorted left to right


def test_synthetic_set_loads_through_the_tusimple_path_with_true_alignment(synthetic_root: Path):
    ds = TuSimpleClips(synthetic_root, "train.json", clip=ClipOptions(num_frames=4, image_size=SIZE, align="true"))
    s = ds[0]
    check_sample_like = s["frames"].shape == (4, 3, *SIZE)
    assert check_sample_like
    k = s["key_from_hist"].numpy()
    np.testing.assert_allclose(k[-1], np.eye(3), atol=1e-6)
    assert not np.allclose(k[0], np.eye(3), atol=1e-3)  # the camera moved: the alignment is not identity
    none = TuSimpleClips(synthetic_root, "train.json", clip=ClipOptions(num_frames=4, image_size=SIZE, align="none"))
    np.testing.assert_allclose(none[0]["key_from_hist"].numpy(), np.repeat(np.eye(3)[None], 4, 0))


# --- bad data ---------------------------------------------------------------------------------------


def test_missing_frame_raises_naming_the_file_or_is_skipped(tusimple_root: Path):
    (tusimple_root / "clips/0313-1/100/18.jpg").unlink()
    with pytest.raises(DataError, match=r"18\.jpg"):
        TuSimpleClips(tusimple_root, "label_data.json", clip=ClipOptions(num_frames=4, image_size=SIZE, align="none"))
    with pytest.warns(UserWarning, match=r"18\.jpg"):
        ds = TuSimpleClips(
            tusimple_root,
            "label_data.json",
            clip=ClipOptions(num_frames=4, image_size=SIZE, align="none"),
            on_error="skip",
        )
    assert len(ds) == 1 and ds[0]["meta"]["raw_file"] == "clips/0313-1/200/20.jpg"
    assert len(ds.skipped) == 1


def test_unreadable_image_raises_or_uses_the_next_sample(tusimple_root: Path):
    (tusimple_root / "clips/0313-1/100/20.jpg").write_bytes(b"not a jpeg")
    ds = TuSimpleClips(tusimple_root, "label_data.json", clip=ClipOptions(num_frames=2, image_size=SIZE, align="none"))
    with pytest.raises(DataError, match=r"100/20\.jpg"):
        ds[0]
    skip = TuSimpleClips(
        tusimple_root, "label_data.json", clip=ClipOptions(num_frames=2, image_size=SIZE, align="none"), on_error="skip"
    )
    with pytest.warns(UserWarning, match="cannot read image"):
        s = skip[0]
    assert s["meta"]["raw_file"].endswith("200/20.jpg")


def test_label_path_outside_root_and_mismatched_lengths(tusimple_root: Path):
    label = tusimple_root / "label_data.json"
    good = label.read_text().splitlines()
    outside = json.dumps({"raw_file": "../../etc/20.jpg", "lanes": [], "h_samples": [1]})
    mismatched = json.dumps({"raw_file": "clips/0313-1/100/20.jpg", "lanes": [[1, 2]], "h_samples": [1, 2, 3]})
    label.write_text("\n".join([good[0], outside, mismatched, "{oops"]) + "\n")
    with pytest.raises(DataError, match="outside the data root"):
        TuSimpleClips(tusimple_root, "label_data.json", clip=ClipOptions(num_frames=1, image_size=SIZE, align="none"))
    label.write_text("\n".join([good[0], mismatched]) + "\n")
    with pytest.raises(DataError, match=r"label_data.json: line 2: lane 0 has 2 x values, h_samples has 3"):
        TuSimpleClips(tusimple_root, "label_data.json", clip=ClipOptions(num_frames=1, image_size=SIZE, align="none"))
    label.write_text("\n".join([good[0], outside, mismatched, "{oops"]) + "\n")
    with pytest.warns(UserWarning):
        ds = TuSimpleClips(
            tusimple_root,
            "label_data.json",
            clip=ClipOptions(num_frames=1, image_size=SIZE, align="none"),
            on_error="skip",
        )
    assert len(ds) == 1 and len(ds.skipped) == 3
    with pytest.raises(DataError, match="outside the data root"):
        TuSimpleClips(
            tusimple_root, "../label_data.json", clip=ClipOptions(num_frames=1, image_size=SIZE, align="none")
        )


def test_bad_culane_lines_name_the_file(culane_root: Path):
    bad = culane_root / "driver_23_30frame/05151649_0422.MP4/00090.lines.txt"
    bad.write_text("1 2 3\n")
    with pytest.raises(DataError, match=r"00090.lines.txt: line 1: odd number of coordinates"):
        CULaneClips(culane_root, "list/train_gt.txt", clip=ClipOptions(num_frames=1, image_size=SIZE, align="none"))


def test_bad_options_are_refused(tusimple_root: Path):
    for kwargs, match in [
        ({"num_frames": 0}, "num_frames"),
        ({"stride": 0}, "stride"),
        ({"align": "magic"}, "align"),
    ]:
        with pytest.raises(ValueError, match=match):  # the clip options check themselves, once
            ClipOptions(image_size=SIZE, **kwargs)
    with pytest.raises(ValueError, match="cache_dir"):
        TuSimpleClips(tusimple_root, "label_data.json", clip=ClipOptions(image_size=SIZE, align="cache"))
    for kwargs, match in [({"on_error": "ignore"}, "on_error"), ({"frame_lookup": "random"}, "frame_lookup")]:
        with pytest.raises(ValueError, match=match):
            TuSimpleClips(tusimple_root, "label_data.json", clip=ClipOptions(image_size=SIZE, align="none"), **kwargs)
    with pytest.raises(TypeError, match="clip must be a ClipOptions"):
        TuSimpleClips(tusimple_root, "label_data.json", clip={"num_frames": 2})
    with pytest.raises(DataError, match="not a folder"):
        TuSimpleClips(tusimple_root / "nope", "label_data.json")


def test_the_clip_options_are_declared_once(tusimple_root: Path) -> None:
    """A dataset takes `ClipOptions` whole: none of its fields is a parameter of a dataset again (with another
    default), a dataset made without one reads clips as `ClipOptions()` says, and the sky cut reaches its default
    transform."""
    import inspect
    from dataclasses import fields

    from stamlane.data.clips import ClipDataset
    from stamlane.data.frames import FolderClips
    from stamlane.data.layouts import DATASETS

    names = {f.name for f in fields(ClipOptions)}
    for cls in (ClipDataset, FolderClips, *DATASETS.values()):
        assert names.isdisjoint(inspect.signature(cls).parameters), cls.__name__
    assert inspect.signature(ClipDataset).parameters["clip"].default == ClipOptions()
    clip = ClipOptions(num_frames=2, stride=2, image_size=SIZE, crop_top=0.25, align="none")
    ds = TuSimpleClips(tusimple_root, "label_data.json", clip=clip)
    assert ds.clip is clip and (ds.num_frames, ds.image_size) == (2, SIZE) and ds.transform.crop_top == 0.25
    assert ds[0]["frames"].shape == (2, 3, *SIZE)


def test_frame_order_compares_numbers_as_numbers():
    names = ["10.jpg", "2.jpg", "1.jpg", "20.jpg", "frame_9.png", "frame_10.png", "a.jpg"]
    assert sorted(names, key=frame_order) == [
        "1.jpg",
        "2.jpg",
        "10.jpg",
        "20.jpg",
        "a.jpg",
        "frame_9.png",
        "frame_10.png",
    ]


def test_sorted_history_follows_the_frame_numbers_not_the_characters(tmp_path: Path):
    """TuSimple-style clips number frames 1..20: the history of 10.jpg is 8.jpg and 9.jpg, not 1.jpg (which
    plain name sorting would put just before 10.jpg)."""
    import cv2

    clip = tmp_path / "clips" / "c"
    clip.mkdir(parents=True)
    for i in range(1, 13):
        cv2.imwrite(str(clip / f"{i}.jpg"), np.full((H, W, 3), 10 * i, np.uint8))
    label = {"lanes": [[10, 20, 30]], "h_samples": [20, 40, 60], "raw_file": "clips/c/10.jpg"}
    (tmp_path / "labels.json").write_text(json.dumps(label) + "\n")
    ds = TuSimpleClips(
        tmp_path, "labels.json", clip=ClipOptions(num_frames=3, image_size=SIZE, align="none"), frame_lookup="sorted"
    )
    assert [Path(p).name for p in ds[0]["meta"]["frame_paths"]] == ["8.jpg", "9.jpg", "10.jpg"]
