"""``stamlane stream VIDEO``: lanes of every frame of a video with `StreamingPredictor`.

Usage::

    stamlane stream drive.mp4 --ckpt outputs/demo/stam4-s0/run/checkpoints/last.ckpt [--out DIR]
    stamlane stream frames_dir/ --config configs/demo.yaml [--ckpt CKPT]

``VIDEO`` is a video file or a folder of frames (in name order, ``2.jpg`` before ``10.jpg``). The network
comes from a checkpoint written by ``stamlane fit`` (``--ckpt``; T, the input size and the horizon row are read
from it) or is built from a training config (``--config``, with the weights of ``--ckpt`` when given, else
untrained). Writes under ``--out`` (default ``outputs/stream/<VIDEO name>``):

- ``lanes.jsonl``: one line per frame, ``{"frame": i, "lanes": [[[x, y], ...], ...], "run_time": ms,
  "aligned": [ok per history slot]}``, points in original pixels;
- ``overlay.mp4`` (mp4v): each frame with its lanes drawn (``--no-video`` to skip);
- with ``--tusimple``, ``predictions.json`` (TuSimple json-lines), with ``--culane``, ``lines/<sequence>/<frame>
  .lines.txt``: what ``stamlane-eval tusimple | culane | video`` score, frames named ``<sequence>/<frame name>``
  (``--sequence``, ``--first-frame``, ``--h-samples``; `stamlane.stream.eval_outputs`).

Every file is written under a temporary name and renamed when the stream ends (`stamlane.safety.guard.atomic_path`): a
failed run leaves the previous results whole. A progress bar shows frames per second. Bad input: one line on
stderr, exit status 2.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections import deque
from collections.abc import Iterator
from contextlib import ExitStack
from pathlib import Path
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np
from stamlane_eval.cli_tools import OneLineParser, parse_or_status

from stamlane.align.homography import ALIGN_PRESETS, align_preset
from stamlane.predict.writers import TusimpleWriter
from stamlane.safety.boundary import run_command
from stamlane.safety.budget import MAX_FPS, check_clip, check_frames, check_rate, check_size
from stamlane.safety.guard import atomic_path, check_outputs, make_folder, temporary_name
from stamlane.safety.images import open_video, read_image
from stamlane.safety.owner import claim, mark
from stamlane.stream.eval_outputs import (
    DEFAULT_FIRST_FRAME,
    EvalOutputs,
    atomic_folder,
    check_h_samples,
    check_sequence,
    folder_temporaries,
    frame_namer,
)
from stamlane.weights import resolve

if TYPE_CHECKING:
    from stamlane.training.stored import StoredModel

__all__ = ["build_parser", "iter_frames", "load_predictor", "main"]


class StreamError(Exception):
    """Bad input to ``stamlane stream`` (reported as one line, exit status 2)."""


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(prog="stamlane stream", description=__doc__.split("\n\n")[0])
    parser.add_argument("video", help="a video file or a folder of frames (in name order, numbers compared as numbers)")
    parser.add_argument(
        "--ckpt", type=resolve, help="checkpoint written by `stamlane fit`, a run folder, or a shipped model's name"
    )
    parser.add_argument("--config", help="training config to build the network from (weights from --ckpt if given)")
    parser.add_argument("--out", help="output folder (default outputs/stream/<VIDEO name>)")
    parser.add_argument("--num-frames", type=int, help="T, frames fused (default: as trained)")
    parser.add_argument(
        "--image-size", type=int, nargs=2, metavar=("H", "W"), help="network input (default: as trained)"
    )
    parser.add_argument("--horizon-row", type=int, help="first ground row in original pixels, for the alignment")
    parser.add_argument(
        "--no-align", action="store_true", help="fuse unaligned history features (default: as the model was trained)"
    )
    parser.add_argument(
        "--align-preset",
        choices=tuple(ALIGN_PRESETS),
        help="the ORB settings of the alignment (default: the checkpoint's data.clip.align_preset, else standard; "
        "fast: faster estimates, docs/alignment.md)",
    )
    parser.add_argument("--max-frames", type=int, help="stop after this many frames")
    parser.add_argument("--no-video", action="store_true", help="do not write overlay.mp4")
    parser.add_argument("--fps", type=float, help="frame rate of overlay.mp4 (default: the video's, else 10)")
    parser.add_argument(
        "--device",
        default="auto",
        help="where the network runs: cpu, cuda, cuda:N (default auto: the GPU where there is one); alignment and "
        "decoding stay on the CPU",
    )
    parser.add_argument(
        "--bf16",
        choices=["auto", "true", "false"],
        help="bfloat16 autocast (default: the model's; auto: where the CPU runs it natively; false: float32, as the "
        "exported .onnx)",
    )
    scored = parser.add_argument_group("outputs the evaluators read (stamlane-eval tusimple | culane | video)")
    scored.add_argument("--tusimple", action="store_true", help="also write predictions.json, TuSimple json-lines")
    scored.add_argument("--culane", action="store_true", help="also write lines/<sequence>/<frame>.lines.txt")
    scored.add_argument(
        "--sequence", help="the folder frames are named under (default: the frames folder's name or the video's stem)"
    )
    scored.add_argument(
        "--first-frame",
        help=f"a video's first frame name, the next counted on (default {DEFAULT_FIRST_FRAME}; 1.jpg for TuSimple)",
    )
    scored.add_argument(
        "--h-samples",
        type=int,
        nargs=3,
        metavar=("START", "STOP", "STEP"),
        help="rows of the lanes, range(START, STOP, STEP): the ground truth's for stamlane-eval tusimple "
        "(default: every y_step rows)",
    )
    return parser


def iter_frames(
    source: Path, max_frames: int | None = None, first_frame: str = DEFAULT_FIRST_FRAME
) -> tuple[Iterator[tuple[str, np.ndarray]], int | None, float | None]:
    """Frames of a video file or an image folder: ``(iterator of (name, BGR uint8 image), count or None, fps or
    None)``; a folder's frames keep their file names, a video's are counted on from ``first_frame``
    (`stamlane.stream.eval_outputs.frame_namer`)."""
    if source.is_dir():
        from stamlane.data.clips import IMAGE_SUFFIXES, frame_order

        paths = sorted(
            (p for p in source.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES), key=lambda p: frame_order(p.name)
        )
        if not paths:
            raise StreamError(f"{source} holds no image ({', '.join(IMAGE_SUFFIXES)})")
        paths = paths[:max_frames] if max_frames else paths

        def read_images() -> Iterator[tuple[str, np.ndarray]]:
            for path in paths:
                image = read_image(path)
                if image is None:
                    raise StreamError(f"cannot read image {path}")
                yield path.name, image

        return read_images(), len(paths), None
    name = frame_namer(first_frame)
    capture = open_video(source, StreamError)
    count = int(capture.get(cv2.CAP_PROP_FRAME_COUNT)) or None
    fps = float(capture.get(cv2.CAP_PROP_FPS)) or None
    if fps is not None and not (math.isfinite(fps) and 0 < fps <= MAX_FPS):  # a header's absurd rate: the default
        fps = None
    if max_frames and count:
        count = min(count, max_frames)

    def read_video() -> Iterator[tuple[str, np.ndarray]]:
        n = 0
        try:
            while not max_frames or n < max_frames:
                ok, frame = capture.read()
                if not ok:
                    break
                n += 1
                yield name(n - 1), frame
        finally:
            capture.release()
        if n == 0:
            raise StreamError(f"no frame could be decoded from {source}")

    return read_video(), count, fps


def _open(args: argparse.Namespace) -> StoredModel:
    """The model the command line names: a stored one (``--ckpt``: a checkpoint, a run folder or a shipped name,
    opened once, `stamlane.training.stored.StoredModel`), or one built from a training config (``--config``, with
    the weights of ``--ckpt`` when given, else untrained), its settings read as a stored model's."""
    from stamlane.safety.checkpoints import CheckpointError, read_checkpoint
    from stamlane.training.stored import ModelSettings, StoredModel

    if not args.config:
        if not args.ckpt:
            raise StreamError("give --ckpt CKPT or --config CFG")
        try:  # built from the closed registry, nothing imported; the checkpoint read once
            return StoredModel.open(args.ckpt)
        except CheckpointError as err:
            raise StreamError(str(err)) from None
    from stamlane.training.runs import run_cli

    if not Path(args.config).is_file():
        raise StreamError(f"config {args.config} does not exist")
    # a bad config raises (one line at the boundary) instead of printing jsonargparse's usage
    cli = run_cli(["--config", args.config], run=False, parser_kwargs={"exit_on_error": False})
    module = cli.model
    if args.ckpt:
        try:
            module.load_state_dict(read_checkpoint(args.ckpt)["state_dict"])
        except CheckpointError as err:
            raise StreamError(str(err)) from None
        except RuntimeError as err:  # another network: missing / unexpected keys, other shapes
            first = str(err).strip().splitlines()[0]
            raise StreamError(f"checkpoint {args.ckpt} does not fit the network of {args.config}: {first}") from None
    try:
        settings = ModelSettings.of(module, cli.datamodule.clip)
    except ValueError as err:
        raise StreamError(f"config {args.config}: {err}") from None
    return StoredModel(Path(args.ckpt or args.config), module.eval(), settings)


def _device(name: str) -> Any:
    """The ``--device`` as a ``torch.device`` that this machine has (``auto``: the first GPU where there is one)."""
    import torch

    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    try:
        device = torch.device(name)
    except RuntimeError:
        raise StreamError(f"--device {name!r} is not a device: give cpu, cuda, cuda:N or auto") from None
    if device.type not in ("cpu", "cuda"):
        raise StreamError(f"--device {name!r}: stamlane stream runs on cpu or cuda")
    if device.type == "cuda" and not (torch.cuda.is_available() and (device.index or 0) < torch.cuda.device_count()):
        raise StreamError(f"--device {name!r}: this machine has {torch.cuda.device_count()} CUDA device(s)")
    return device


def load_predictor(args: argparse.Namespace) -> Any:
    """The `StreamingPredictor` the command line asks for: the model's stored settings
    (`stamlane.training.stored.ModelSettings`: alignment on or off, its preset and horizon row, T, size, crop,
    decoding, bfloat16), each flag given replacing its setting."""
    from stamlane.stream.predictor import StreamingPredictor

    if args.ckpt and not Path(args.ckpt).exists():
        raise StreamError(f"checkpoint {args.ckpt} does not exist")
    device = _device(args.device)
    model = _open(args)
    model.module.eval().to(device)
    overrides: dict[str, Any] = {}
    if args.no_align:
        overrides["align"] = False
    if args.bf16 is not None:
        from stamlane.training.hardware import resolve_bf16

        overrides["bf16"] = resolve_bf16({"true": True, "false": False}.get(args.bf16, args.bf16), device.type)
    num_frames = args.num_frames or model.settings.num_frames
    image_size = tuple(args.image_size or model.settings.image_size)
    check_clip(num_frames, list(image_size), "the streamed clip")  # the network's or the flags' size, one budget
    overrides |= {"num_frames": int(num_frames), "image_size": image_size}
    if args.horizon_row is not None:
        overrides["horizon_row"] = args.horizon_row
    if args.align_preset is not None:
        overrides["align_config"] = align_preset(args.align_preset)
    if args.h_samples is not None:  # the lanes sampled at the benchmark's rows, as `stamlane predict` does
        overrides["y_samples"] = check_h_samples(args.h_samples)
    return StreamingPredictor.from_stored(model, **overrides)


def _lanes_json(lanes: list[np.ndarray]) -> list[list[list[float]]]:
    return [[[round(float(x), 2), round(float(y), 2)] for x, y in lane] for lane in lanes]


def _sequence(args: argparse.Namespace, source: Path) -> str | None:
    """Check the flags of the evaluator outputs; the sequence their frames are named under (None without them)."""
    if args.h_samples is not None:
        check_h_samples(args.h_samples)
    if args.sequence is not None:
        check_sequence(args.sequence)
    if args.first_frame is not None:
        frame_namer(args.first_frame)
        if source.is_dir():
            raise StreamError("--first-frame names a video's frames; the frames of a folder keep their own names")
    if not (args.tusimple or args.culane):
        if args.sequence is not None or args.first_frame is not None:
            raise StreamError("--sequence and --first-frame name the frames of --tusimple / --culane: give one of them")
        return None
    if args.sequence is not None:
        return str(args.sequence)
    if source.is_dir():
        return str(check_sequence(source.resolve().name, "--sequence (default: the folder's name)"))
    return check_sequence(source.stem, "--sequence (default: the video's name)")


def run(args: argparse.Namespace) -> int:
    source = Path(args.video)
    if not source.exists():
        raise StreamError(f"{source} does not exist")
    if args.max_frames is not None and args.max_frames < 1:
        raise StreamError(f"--max-frames must be >= 1, got {args.max_frames}")
    if args.fps is not None:
        check_rate(args.fps, "--fps")  # inf or nan would never finish writing the video
    if args.num_frames is not None:
        check_frames(args.num_frames, "--num-frames")
    if args.image_size is not None:
        check_size(args.image_size, "--image-size")
    if args.num_frames is not None and args.image_size is not None:
        check_clip(args.num_frames, args.image_size, "--num-frames x --image-size")
    sequence = _sequence(args, source)
    # one folder per source: a second source of the same name gets outputs/stream/<name>-2 (stamlane.safety.owner)
    owner = {"command": "stream", "source": str(source.resolve())}
    out_dir = claim(args.out or Path("outputs/stream") / source.stem, owner, "--out", chosen=not args.out)
    paths: dict[str, Path | None] = {
        "lanes": out_dir / "lanes.jsonl",
        "video": None if args.no_video else out_dir / "overlay.mp4",
        "tusimple": out_dir / "predictions.json" if args.tusimple else None,
        "culane": out_dir / "lines" if args.culane else None,
    }
    files = [p for key, p in paths.items() if p is not None and key != "culane"]
    folders = [out_dir, *([paths["culane"], *folder_temporaries(paths["culane"])] if paths["culane"] else [])]
    check_outputs(  # no output replaces the video, the checkpoint or the config, nor lands among the frames
        [*files, *map(temporary_name, files)], [source, args.ckpt, args.config], folders=folders, protected=[source]
    )
    frames, count, fps = iter_frames(source, args.max_frames, args.first_frame or DEFAULT_FIRST_FRAME)
    predictor = load_predictor(args)
    make_folder(out_dir, "--out")
    with ExitStack() as stack:  # each under a temporary name, renamed when the stream ends: a failure keeps the old
        temps = {
            key: stack.enter_context(atomic_folder(path) if key == "culane" else atomic_path(path))
            for key, path in paths.items()
            if path is not None
        }
        written, seconds = _stream(args, source, frames, count, fps, predictor, temps, sequence)
    mark(out_dir, owner)  # once the results are whole: a failed run leaves the folder as it was
    wrote = [str(path) for path in paths.values() if path is not None]
    print(
        f"stamlane stream: {written} frames in {seconds:.1f} s ({written / max(seconds, 1e-9):.1f} frames/s); "
        f"wrote {', '.join(wrote)}"
    )
    return 0


def _stream(
    args: argparse.Namespace,
    source: Path,
    frames: Iterator[tuple[str, np.ndarray]],
    count: int | None,
    fps: float | None,
    predictor: Any,
    paths: dict[str, Path],
    sequence: str | None,
) -> tuple[int, float]:
    """Run the predictor over the frames, writing each output of ``paths`` (``lanes``, and ``video``, ``tusimple``,
    ``culane`` when there); returns (frames, seconds)."""
    import torch
    from tqdm import tqdm

    from stamlane.predict.overlay import draw_lanes

    video_path = paths.get("video")
    writer = None
    written = 0
    start = time.perf_counter()
    with ExitStack() as files, torch.inference_mode():
        jsonl = files.enter_context(open(paths["lanes"], "w"))
        # the TuSimple lines and CULane files of `stamlane predict`'s writer (stamlane.predict.writers)
        tusimple = files.enter_context(TusimpleWriter(paths["tusimple"])) if "tusimple" in paths else None
        scored = None
        if sequence is not None:
            y_step = predictor.postprocess.y_step
            scored = EvalOutputs(sequence, tusimple, paths.get("culane"), predictor.y_samples, y_step)
        bar = files.enter_context(tqdm(frames, total=count, desc=f"stream {source.name}", unit="frame"))
        # (closed on the way out, an error too: its line then starts a line of its own)
        read: deque[tuple[str, np.ndarray]] = deque()  # the frames read ahead, in order

        def images() -> Iterator[np.ndarray]:
            for name, image in bar:
                read.append((name, image))
                yield image

        t0 = time.perf_counter()
        for out in predictor.run(images()):  # reading, alignment features and lane decoding beside the network
            name, image = read.popleft()
            ms = (time.perf_counter() - t0) * 1000.0  # since the previous frame's lanes: the stream's time a frame
            t0 = time.perf_counter()
            record = {
                "frame": out.index,
                "lanes": _lanes_json(out.lanes),
                "run_time": round(ms, 2),
                "aligned": [bool(a.ok) for a in out.alignments],
            }
            jsonl.write(json.dumps(record) + "\n")
            if scored is not None:
                scored.write(name, out.lanes, ms, image.shape[0])
            if video_path is not None:
                if writer is None:
                    frame_wh = (image.shape[1], image.shape[0])  # OpenCV's (W, H)
                    writer = cv2.VideoWriter(
                        str(video_path), cv2.VideoWriter.fourcc(*"mp4v"), args.fps or fps or 10.0, frame_wh
                    )
                writer.write(draw_lanes(image, out.lanes))
            written += 1
    if writer is not None:
        writer.release()
    if video_path is not None and not video_path.is_file():
        raise StreamError(f"the overlay video could not be written ({video_path.suffix} with the mp4v codec)")
    return written, time.perf_counter() - start


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``stamlane stream``; returns the exit status."""
    args = parse_or_status(build_parser(), sys.argv[1:] if argv is None else argv)
    if isinstance(args, int):
        return args
    return run_command("stamlane stream", lambda: run(args), StreamError)


if __name__ == "__main__":
    sys.exit(main())
