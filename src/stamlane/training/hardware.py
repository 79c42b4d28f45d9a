"""What the machine runs fast: native bfloat16 or not.

bf16 autocast is faster than float32 on CPUs with AMX or AVX512-BF16 and much SLOWER on CPUs without them
(AVX2-only laptops and many cloud cores), where oneDNN emulates it (measured: docs/results/timings/). ``bf16="auto"`` in
`stamlane.training.module.StamLaneModule` asks `native_bf16` which one this machine is.
"""

from __future__ import annotations

import os
import platform
from pathlib import Path

import torch

__all__ = ["cpu_name", "kernels_capped", "native_bf16", "resolve_bf16"]


def native_bf16(device_type: str = "cpu") -> bool:
    """True where ``device_type`` computes in bfloat16 natively (CPU: AMX tiles or AVX512-BF16; CUDA:
    ``torch.cuda.is_bf16_supported``)."""
    if device_type == "cuda":
        return bool(torch.cuda.is_available() and torch.cuda.is_bf16_supported())
    if device_type != "cpu":
        return False
    cpu = torch.cpu
    checks = ("_is_amx_tile_supported", "_is_avx512_bf16_supported")  # private, but what torch itself uses
    return any(bool(getattr(cpu, name, lambda: False)()) for name in checks) and not kernels_capped()


def kernels_capped() -> bool:
    """Whether this process's kernels were capped below the CPU's bfloat16 instructions, which are then emulated:
    ``ATEN_CPU_CAPABILITY`` below ``avx512`` or ``ONEDNN_MAX_CPU_ISA`` below ``AVX512_CORE_BF16`` (how an AVX2-only
    machine is imitated on a newer one: docs/training.md)."""
    if os.environ.get("ATEN_CPU_CAPABILITY") and torch.backends.cpu.get_cpu_capability() != "AVX512":
        return True
    isa = os.environ.get("ONEDNN_MAX_CPU_ISA", "ALL").upper()
    return isa != "ALL" and not any(tag in isa for tag in ("BF16", "AMX", "AVX10", "FP16"))


def resolve_bf16(value: bool | str, device_type: str = "cpu") -> bool:
    """The ``bf16`` option as a bool: ``"auto"`` becomes `native_bf16`; ``True`` / ``False`` stay.

    Raises:
        ValueError: for any other value.
    """
    if isinstance(value, bool):
        return value
    if value == "auto":
        return native_bf16(device_type)
    raise ValueError(f"bf16 must be true, false or 'auto', got {value!r}")


def cpu_name() -> str:
    """The CPU's model name (``/proc/cpuinfo``'s ``model name``), else what ``platform`` knows: what a timing or a
    run record says it came from."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()
