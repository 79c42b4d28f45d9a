"""Readers and writers of the benchmark formats, one module per format, with errors that name the file, the line and
the problem.

- `stamlane_eval.io.tusimple`: TuSimple json-lines (``raw_file``, ``lanes``, ``h_samples`` / ``run_time``), THE
  check of the format, TuSimple lanes as points for the CULane metric, the line lane.py prints;
- `stamlane_eval.io.culane`: CULane / ApolloScape text, one ``.lines.txt`` per image (``x1 y1 x2 y2 ...`` per
  lane), list files and folders, the text the C++ tool writes;
- `stamlane_eval.io.vil100`: VIL-100 json, one file per frame;
- `stamlane_eval.io.video`: sequences of frames in any of the three (VIL-100, CULane text per frame, TuSimple
  records grouped by the folder of ``raw_file``), ``--sizes`` files, `Frame`;
- `stamlane_eval.io.files`: what they share: bounded reading (`read_text`), THE check of a path inside a root
  folder (`inside`, `Inside`), THE atomic writer (`write_atomic`, `write_jsonl`);
- `stamlane_eval.io.limits`: the memory limits (``MAX_*``, `check_image_size`, `CanvasBudget`).

Every public name is importable from ``stamlane_eval.io`` itself.
"""

from stamlane_eval.io.culane import (
    IMAGE_SUFFIXES,
    cpp_stream_doubles,
    cpp_tool_text,
    culane_entries,
    culane_lines_path,
    images_beside,
    read_culane_folders,
    read_culane_lines,
)
from stamlane_eval.io.files import Inside, LaneFileError, image_key, inside, read_text, write_atomic, write_jsonl
from stamlane_eval.io.limits import (
    MAX_COMPARED_CELLS,
    MAX_COORDINATE,
    MAX_DRAWN_PIXELS,
    MAX_FILE_BYTES,
    MAX_IMAGE_POINTS,
    MAX_IMAGE_SIDE,
    MAX_LANE_POINTS,
    MAX_LANE_WIDTH,
    MAX_LANES,
    MAX_TUSIMPLE_VALUES,
    CanvasBudget,
    check_image_size,
)
from stamlane_eval.io.tusimple import (
    LABEL_RULES,
    TuSimpleFile,
    TuSimpleInputError,
    check_tusimple,
    duplicate_raw_file,
    iter_tusimple,
    lane_py_line,
    read_tusimple,
    tusimple_lanes,
    tusimple_lanes_by_image,
    tusimple_points,
    tusimple_record_error,
)
from stamlane_eval.io.video import (
    TUSIMPLE_SUFFIXES,
    Frame,
    TuSimpleFrames,
    VideoInput,
    is_tusimple_input,
    listed_frames,
    read_sizes,
    read_tusimple_frames,
    read_video,
    tusimple_frame_key,
    video_frames,
)
from stamlane_eval.io.vil100 import read_vil100_json

__all__ = [
    "IMAGE_SUFFIXES",
    "LABEL_RULES",
    "MAX_COMPARED_CELLS",
    "MAX_COORDINATE",
    "MAX_DRAWN_PIXELS",
    "MAX_FILE_BYTES",
    "MAX_IMAGE_POINTS",
    "MAX_IMAGE_SIDE",
    "MAX_LANES",
    "MAX_LANE_POINTS",
    "MAX_LANE_WIDTH",
    "MAX_TUSIMPLE_VALUES",
    "TUSIMPLE_SUFFIXES",
    "CanvasBudget",
    "Frame",
    "Inside",
    "LaneFileError",
    "TuSimpleFile",
    "TuSimpleFrames",
    "TuSimpleInputError",
    "VideoInput",
    "check_image_size",
    "check_tusimple",
    "cpp_stream_doubles",
    "cpp_tool_text",
    "culane_entries",
    "culane_lines_path",
    "duplicate_raw_file",
    "image_key",
    "images_beside",
    "inside",
    "is_tusimple_input",
    "iter_tusimple",
    "lane_py_line",
    "listed_frames",
    "read_culane_folders",
    "read_culane_lines",
    "read_sizes",
    "read_text",
    "read_tusimple",
    "read_tusimple_frames",
    "read_video",
    "read_vil100_json",
    "tusimple_frame_key",
    "tusimple_lanes",
    "tusimple_lanes_by_image",
    "tusimple_points",
    "tusimple_record_error",
    "video_frames",
    "write_atomic",
    "write_jsonl",
]
