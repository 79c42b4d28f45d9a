"""How large an input the shipped models can take and still stream at 15 frames/s: ``stamlane stream``'s whole
loop per frame (resize and crop, alignment where the model aligns, the network, the lane decoding) at several
network input sizes, side by side.

    python benchmarks/input_size.py [--ckpt single-dashcam stam4-dashcam] [--sizes 80x256 128x384 160x512]
                                    [--source ../shared/data/real/solidWhiteRight.mp4] [--frames 60]
                                    [--repeats 3] [--threads 2] [--out outputs/bench/input_size.json]

Issue #56's constraint: the shipped default keeps ``stamlane stream`` at >= 15 frames/s on 2 CPU cores at 640x360.
The frames of ``--source`` are resized to 640x360 once, before the timing (a user's video decoded is not the model's
cost). Every model is opened as ``stamlane stream`` opens it (`StreamingPredictor.from_stored`: T, crop, alignment,
bfloat16 as stored) with ``image_size`` replaced: the network is fully convolutional, so the trained weights run at
any size that is a multiple of its stride; the decoding's pixel counts follow the size
(`PostprocessConfig.reference_size`). The lanes drawn at a size the model was not trained at are not a measure of
anything here: only the time is.

Each repeat runs every (model, size) over the same ``--frames`` frames in turn (`in_turn`, alternating: ABBA), after
one untimed pass of each; a repeat starts a fresh video (`StreamingPredictor.reset`). Prints the median frames/s
and the network's share of a frame, and writes ``--out`` (json: per model and size the frames/s of every repeat, the
median, the machine and its load before and after). Exit status 2 with one line where an option or the source
cannot be used.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")  # before torch: spinning OpenMP threads starve a shared CPU

import argparse
import re
import sys
import time
from pathlib import Path

from _harness import BenchInputError, Within, fail, guard_out, in_turn, load_1min, machine, option_problem, write_result

REPO = Path(__file__).resolve().parents[1]
DEFAULT_SOURCE = REPO.parent / "shared" / "data" / "real" / "solidWhiteRight.mp4"
STREAM_SIZE = (640, 360)  # (width, height) of the constraint
TARGET_FPS = 15.0
SIZE = re.compile(r"^(\d+)x(\d+)$")


def parse_size(text: str) -> tuple[int, int]:
    """``"HxW"`` as ``(H, W)``, for argparse."""
    match = SIZE.match(text)
    if not match:
        raise argparse.ArgumentTypeError(f"a size is HxW (e.g. 160x512), got {text!r}")
    return int(match[1]), int(match[2])


MAX_FRAMES = 1000
"""The most ``--frames``: they are held in memory at 640x360 (0.7 MB each, 0.7 GB at the most)."""


def read_frames(source: Path, count: int) -> list:
    """The first ``count`` frames of ``source`` (a video or an image folder), resized to `STREAM_SIZE`."""
    import cv2

    from stamlane.stream.cli import StreamError, iter_frames

    try:
        frames, _, _ = iter_frames(source, max_frames=count)
        images = [cv2.resize(image, STREAM_SIZE, interpolation=cv2.INTER_AREA) for _, image in frames]
    except StreamError as err:
        raise BenchInputError(str(err)) from None
    if len(images) < count:
        raise BenchInputError(f"{source} holds {len(images)} frames, fewer than --frames {count}")
    return images


def predictor(ckpt: str, size: tuple[int, int]):
    """``ckpt`` opened as ``stamlane stream`` opens it, at the network input ``size``."""
    from stamlane.safety.checkpoints import CheckpointError
    from stamlane.stream.predictor import StreamingPredictor
    from stamlane.training.stored import StoredModel

    try:
        return StreamingPredictor.from_stored(StoredModel.open(ckpt), image_size=size)
    except (CheckpointError, ValueError) as err:
        raise BenchInputError(f"{ckpt} at {size[0]}x{size[1]}: {err}") from None


def stream_seconds(stream, frames: list) -> tuple[float, float]:
    """Seconds for ``frames`` as one fresh video, and the seconds of them the network took."""
    stream.reset()
    network = 0.0
    start = time.perf_counter()
    for out in stream.run(frames):
        network += out.timings.get("network", 0.0) / 1000.0
    return time.perf_counter() - start, network


def main(argv: list[str] | None = None) -> int:
    prog = "input_size.py"
    parser = argparse.ArgumentParser(prog=prog, description=__doc__.split("\n\n")[0])
    parser.add_argument("--ckpt", nargs="+", default=["single-dashcam", "stam4-dashcam"])
    parser.add_argument("--sizes", nargs="+", type=parse_size, default=[(80, 256), (128, 384), (160, 512)])
    parser.add_argument("--source", type=Path, default=DEFAULT_SOURCE)
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--out", type=Path, default=Path("outputs/bench/input_size.json"))
    args = parser.parse_args(argv)
    ranges = {"frames": Within(2, MAX_FRAMES), "repeats": Within(1, 50), "threads": Within(1, 256)}
    if (problem := option_problem(vars(args), ranges=ranges)) is not None:
        return fail(prog, problem)
    if (status := guard_out(prog, args.out)) is not None:
        return status
    import torch

    torch.set_num_threads(args.threads)
    try:
        frames = read_frames(args.source, args.frames)
        streams = {f"{c}@{h}x{w}": predictor(c, (h, w)) for c in args.ckpt for h, w in args.sizes}
    except BenchInputError as err:
        return fail(prog, err)
    load_before = load_1min()
    network: dict[str, list[float]] = {name: [] for name in streams}
    with torch.inference_mode():
        for stream in streams.values():  # warm-up: first calls allocate and pick kernels
            stream_seconds(stream, frames[:4])

        def measure(name: str, repeat: int) -> float:
            seconds, net = stream_seconds(streams[name], frames)
            network[name].append(net / seconds)
            return len(frames) / seconds

        fps = in_turn(measure, list(streams), args.repeats, alternate=True)
    rows = {}
    for name, values in fps.items():
        ckpt, size = name.rsplit("@", 1)
        median = sorted(values)[len(values) // 2]
        share = sorted(network[name])[len(values) // 2]
        rows[name] = {"ckpt": ckpt, "size": size, "fps": values, "median_fps": median, "network_share": share}
        flag = "meets" if median >= TARGET_FPS else "below"
        print(f"{ckpt:>16} {size:>8}: {median:6.2f} frames/s ({flag} {TARGET_FPS:g}), network {share:.0%} of a frame")
    result = {
        "source": str(args.source),
        "stream_size": list(STREAM_SIZE),
        "frames": args.frames,
        "repeats": args.repeats,
        "threads": args.threads,
        "machine": {**machine(), "load_before": load_before, "load_after": load_1min()},
        "rows": rows,
    }
    write_result(args.out, result)
    return 0


if __name__ == "__main__":
    sys.exit(main())
