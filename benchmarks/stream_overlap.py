"""The streaming predictor frame after frame and pipelined (`StreamingPredictor.run`), side by side.

    python benchmarks/stream_overlap.py [--frames 60] [--repeats 3] [--device cpu] [--out outputs/benchmarks/stream_overlap.json]

The shipped 4-frame model (80x256, ORB alignment on the 640x360 frames) on the first ``--frames`` frames of the real
highway video beside the project (``../shared/data/real/solidWhiteRight.mp4``, resized to 640x360; rendered road
frames where it is absent), in turn ``--repeats`` times: ``serial`` (``predictor(image)`` per frame, the video
read in between, as ``stamlane stream`` ran before) and ``pipelined`` (``predictor.run(frames)``: reading and
ORB features of frame t+1 and lane decoding of frame t beside the network on frame t). Prints the medians of the
ms a frame and whether both gave the same lanes, logits and homographies; keeps them in ``--out``.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")  # before torch: spinning OpenMP threads starve a shared CPU

import argparse
import statistics
import sys
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path

import cv2
import numpy as np
from _harness import guard_out, in_turn, load_1min, machine, medians, ratio, timed, write_result

REPO = Path(__file__).resolve().parents[1]
VIDEO = REPO.parent / "shared" / "data" / "real" / "solidWhiteRight.mp4"


def frames(count: int) -> Iterator[np.ndarray]:
    """The video's first ``count`` frames at 640x360, decoded as they are asked for (or rendered road frames)."""
    if VIDEO.is_file():
        capture = cv2.VideoCapture(str(VIDEO))
        try:
            for _ in range(count):
                ok, image = capture.read()
                if not ok:
                    return
                yield cv2.resize(image, (640, 360), interpolation=cv2.INTER_AREA)
        finally:
            capture.release()
        return
    from stamlane.align.egomotion import RoadCamera
    from stamlane.align.synthetic import render_road, road_texture

    camera = RoadCamera(width=640, height=360, focal=500.0, horizon_row=140.0, camera_height=1.5)
    texture = road_texture(seed=3)
    for i in range(count):
        yield render_road(texture, camera, forward=0.5 * (i % 8), yaw=0.002 * (i % 8))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--out", type=Path, default=Path("outputs/benchmarks/stream_overlap.json"))
    args = parser.parse_args(argv)

    if (refused := guard_out("stream_overlap.py", args.out)) is not None:  # before any work
        return refused
    import torch

    from stamlane.stream import StreamingPredictor
    from stamlane.training.stored import StoredModel

    warnings.filterwarnings("ignore")
    torch.set_num_threads(max(1, os.cpu_count() or 1))
    model = StoredModel.open("stam4-synthetic")
    model.module.to(args.device)
    result: dict = machine() | {"device": args.device, "video": VIDEO.is_file(), "load_1min_at_start": load_1min()}
    outputs: dict[str, list] = {}
    ways: dict[str, Callable[[StreamingPredictor], list]] = {
        "serial": lambda predictor: [predictor(image) for image in frames(args.frames)],
        "pipelined": lambda predictor: list(predictor.run(frames(args.frames))),
    }

    def measure(mode: str, _: int) -> float:
        predictor = StreamingPredictor.from_stored(model)  # made before the clock starts
        seconds, outputs[mode] = timed(lambda: ways[mode](predictor))
        return round(seconds * 1000.0 / len(outputs[mode]), 2)

    times = in_turn(measure, list(ways), args.repeats)
    serial, piped = outputs["serial"], outputs["pipelined"]
    same = len(serial) == len(piped) and all(
        torch.equal(a.logits, b.logits)
        and len(a.lanes) == len(b.lanes)
        and all(np.array_equal(x, y) for x, y in zip(a.lanes, b.lanes))
        and all(np.array_equal(x.key_from_hist, y.key_from_hist) for x, y in zip(a.alignments, b.alignments))
        for a, b in zip(serial, piped)
    )
    stages = {k: round(statistics.median(o.timings[k] for o in serial), 2) for k in serial[0].timings}
    med = medians(times)
    result |= {"frames": len(serial), "ms_per_frame": times, "median_ms": med, "serial_stages_ms": stages}
    result |= {"ratio": ratio(times, "serial", "pipelined"), "same_outputs": same}
    result["load_1min_at_end"] = load_1min()
    print(
        f"{len(serial)} frames on {args.device}: serial {med['serial']:.1f} ms a frame {stages}, pipelined "
        f"{med['pipelined']:.1f} (x{result['ratio']:.2f}, medians of {args.repeats} in turn); the same outputs: "
        f"{same}; load {result['load_1min_at_start']} -> {result['load_1min_at_end']}"
    )
    write_result(args.out, result)
    return 0


if __name__ == "__main__":
    sys.exit(main())
