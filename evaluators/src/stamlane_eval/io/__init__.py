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

from stamlane_eval.io import culane, limits, tusimple, video, vil100
from stamlane_eval.io.culane import *  # noqa: F403
from stamlane_eval.io.files import Inside, LaneFileError, image_key, inside, read_text, write_atomic, write_jsonl
from stamlane_eval.io.limits import *  # noqa: F403
from stamlane_eval.io.tusimple import *  # noqa: F403
from stamlane_eval.io.video import *  # noqa: F403
from stamlane_eval.io.vil100 import *  # noqa: F403

# the public names of each module are its own __all__; of files, all but name_problem and path_problem (the checks of
# a path's bytes, for stamlane and the CLI only)
__all__ = ["Inside", "LaneFileError", "image_key", "inside", "read_text", "write_atomic", "write_jsonl"]
__all__ += culane.__all__
__all__ += limits.__all__
__all__ += tusimple.__all__
__all__ += video.__all__
__all__ += vil100.__all__
