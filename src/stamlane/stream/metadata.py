"""What an exported graph needs around it, written into the .onnx itself (``metadata_props``).

A graph alone says its input is ``clip`` (B, T, 3, H, W) float32. To feed it one must also know which rows were
cut before resizing, the colour order, the value range, whether the history is pre-aligned and how, and to read
its outputs the lane decoding settings. `deployment_metadata` collects them from the checkpoint: the module's
hyper-parameters (T, input size, ``crop_top``, post-processing) and the data options the run trained with
(`stamlane.data.options.ClipOptions`: alignment), never from defaults of this file. Every value is JSON text, so
a reader needs nothing but ``json`` and onnxruntime::

    meta = {k: json.loads(v) for k, v in session.get_modelmeta().custom_metadata_map.items()}

Keys (`METADATA_KEYS`; docs/streaming.md "What the .onnx carries"):

``format``            ``"stamlane-onnx/1"``, the version of this layout.
``stamlane_version``  the stamlane that wrote the file.
``checkpoint``, ``checkpoint_sha256``  the checkpoint's file name and SHA-256 of its bytes.
``graph``             ``"clip"``, ``"encoder"`` or ``"fuse_decode"`` (`stamlane.stream.export`).
``input_names``, ``input_shapes``, ``output_names``, ``output_shapes``  read from the graph itself; a dynamic
                      axis is its name (``"batch"``).
``input_layout``      what the axes of the image input mean (the clip graph: ``"B, T, 3, H, W"``, frames
                      oldest first, key frame last).
``num_frames``        T; ``key_frame``: ``"last"``.
``image_size``        ``[H, W]`` of the network input, after the cut and the resize.
``crop_top``          the fraction of the frame's rows cut at the top before resizing.
``resize``            how the frame is mapped to the input (bilinear, pixel centres aligned: the formula).
``colour_order``      ``"RGB"``; ``value_range``: ``[0, 1]``; ``normalisation``: pixel / 255, no mean or std.
``alignment``         how the history was aligned in training: ``history`` (``"pre-aligned"`` or
                      ``"unaligned"``), ``by``, ``source`` (``ClipOptions.align``), ``warp``, ``strategy``,
                      ``horizon_row``; ``null`` when the checkpoint records no data options.
``lane_channel``      the channel of ``logits`` that is "lane" (softmax over the two channels).
``postprocess``       the `stamlane.predict.postprocess.PostprocessConfig` of the model, as a JSON object.
``precision``         ``"float32"``: the graph's arithmetic (parity is measured in it).
``opset``             the ONNX opset.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from stamlane.safety.guard import file_sha256

if TYPE_CHECKING:
    from stamlane.data.options import ClipOptions

__all__ = [
    "FORMAT",
    "LANE_CHANNEL",
    "METADATA_KEYS",
    "annotate",
    "deployment_metadata",
    "read_metadata",
    "trained_crop_top",
]

FORMAT = "stamlane-onnx/1"
"""The version of the metadata layout; a change of a key's meaning changes it."""

LANE_CHANNEL = 1
"""``logits[:, 1]`` is "lane", ``logits[:, 0]`` background (`stamlane.training.module.StamLaneModule.decode`)."""

RESIZE = (
    "bilinear (OpenCV INTER_LINEAR), pixel centres aligned: x_net = (x + 0.5) * W / W0 - 0.5, "
    "y_net = (y - top + 0.5) * H / (H0 - top) - 0.5 with top = crop_top * H0, for a frame of H0 x W0; where "
    "s = sqrt(W / W0 * H / (H0 - top)) < 0.6, the frame is first resized by min(1, 2 s) with OpenCV INTER_AREA "
    "(to about twice the input size, against aliasing) and the map composed with that resize"
)
"""How a frame becomes the network input (`stamlane.data.transforms.ClipTransform`, without augmentation)."""

LAYOUTS = {
    "clip": "B, T, 3, H, W: clips, frames oldest first with the key frame last, RGB channels, rows, columns",
    "encoder": "N, 3, H, W: frames, RGB channels, rows, columns",
    "fuse_decode": "key_stage{i}: the key frame's encoder outputs; history (B, T-1, C, h, w) oldest first; grid "
    "(B, T-1, h, w, 2) where each key cell samples each history frame (grid_sample, align_corners=0)",
}

METADATA_KEYS = (
    "format",
    "stamlane_version",
    "checkpoint",
    "checkpoint_sha256",
    "graph",
    "input_names",
    "input_shapes",
    "output_names",
    "output_shapes",
    "input_layout",
    "num_frames",
    "key_frame",
    "image_size",
    "crop_top",
    "resize",
    "colour_order",
    "value_range",
    "normalisation",
    "alignment",
    "lane_channel",
    "postprocess",
    "precision",
    "opset",
)
"""Every key `deployment_metadata` writes, in order."""


def trained_crop_top(module: Any, clip: ClipOptions | None) -> float:
    """The fraction of rows the network was trained without: the data options' (what cut the frames it saw), else
    the module's record of them (``model.crop_top``, linked from the data), else 0."""
    if clip is not None:
        return float(clip.crop_top)
    return float(getattr(module, "hparams", {}).get("crop_top") or 0.0)


def _alignment(clip: ClipOptions | None) -> dict[str, Any] | None:
    if clip is None:
        return None
    if clip.align == "none":
        history, by = "unaligned", "nothing: the frames are fed as they are"
    else:
        source = {
            "fly": "estimated per clip",
            "cache": "from `stamlane align`'s cache",
            "true": "the synthetic generator's exact ones in training; estimate them",
        }[clip.align]
        history = "pre-aligned"
        by = (
            f"ORB ground-plane homographies key_from_hist ({source}) with stamlane.align.estimate_clip, "
            f"outside the network; each history frame warped with net_from_orig @ key_from_hist"
        )
    return {
        "history": history,
        "by": by,
        "source": clip.align,
        "warp": clip.warp,
        "strategy": clip.align_strategy,
        "preset": clip.align_preset,
        "horizon_row": clip.horizon_row,
    }


def _dims(value_info: Any) -> list[int | str]:
    return [d.dim_param if d.dim_param else int(d.dim_value) for d in value_info.type.tensor_type.shape.dim]


def deployment_metadata(module: Any, clip: ClipOptions | None, checkpoint: str | Path, opset: int) -> dict[str, Any]:
    """What every graph exported from one checkpoint carries (`annotate` adds the graph's own keys).

    Args:
        module: the `stamlane.training.module.StamLaneModule` built from the checkpoint.
        clip: the data options of its run (`stamlane.training.compat.clip_options` of the checkpoint's
            ``datamodule_hyper_parameters``), or None when the checkpoint records none.
        checkpoint: the checkpoint file.
        opset: the ONNX opset of the graphs.

    Raises:
        ValueError: the module records no ``num_frames`` / ``image_size``.
    """
    import stamlane

    stamlane_version = str(stamlane.__version__)
    image_size = module.hparams.get("image_size")
    num_frames = module.num_frames
    if image_size is None or num_frames is None:
        raise ValueError(f"checkpoint {checkpoint} records no num_frames / image_size")
    return {
        "format": FORMAT,
        "stamlane_version": stamlane_version,
        "checkpoint": Path(checkpoint).name,
        "checkpoint_sha256": file_sha256(checkpoint),
        "num_frames": int(num_frames),
        "key_frame": "last",
        "image_size": [int(image_size[0]), int(image_size[1])],
        "crop_top": trained_crop_top(module, clip),
        "resize": RESIZE,
        "colour_order": "RGB",
        "value_range": [0.0, 1.0],
        "normalisation": "pixel / 255 as float32; no mean subtracted, no std divided",
        "alignment": _alignment(clip),
        "lane_channel": LANE_CHANNEL,
        "postprocess": dataclasses.asdict(module.postprocess),
        "precision": "float32",
        "opset": int(opset),
    }


def annotate(path: str | Path, graph: str, common: Mapping[str, Any]) -> dict[str, Any]:
    """Write ``common`` (`deployment_metadata`) and the graph's own keys into the .onnx at ``path``, in place.

    Args:
        path: the exported graph.
        graph: ``"clip"``, ``"encoder"`` or ``"fuse_decode"`` (`stamlane.stream.export`).
        common: the checkpoint's metadata.

    Returns:
        the metadata written, keys in the order of `METADATA_KEYS`.
    """
    import onnx

    if graph not in LAYOUTS:
        raise ValueError(f"graph must be one of {sorted(LAYOUTS)}, got {graph!r}")
    model = onnx.load(str(path))
    own = {
        "graph": graph,
        "input_names": [i.name for i in model.graph.input],
        "input_shapes": {i.name: _dims(i) for i in model.graph.input},
        "output_names": [o.name for o in model.graph.output],
        "output_shapes": {o.name: _dims(o) for o in model.graph.output},
        "input_layout": LAYOUTS[graph],
    }
    metadata = {key: (own | dict(common))[key] for key in METADATA_KEYS}
    del model.metadata_props[:]
    for key, value in metadata.items():
        entry = model.metadata_props.add()
        entry.key, entry.value = key, json.dumps(value)
    onnx.save(model, str(path))
    return metadata


def read_metadata(path: str | Path) -> dict[str, Any]:
    """The ``metadata_props`` of an .onnx, each value decoded from JSON."""
    import onnx

    model = onnx.load(str(path), load_external_data=False)
    return {p.key: json.loads(p.value) for p in model.metadata_props}
