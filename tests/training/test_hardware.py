"""stamlane.training.hardware: bf16 only where the CPU computes it natively."""

from __future__ import annotations

from pathlib import Path

import pytest

from stamlane.training.hardware import kernels_capped, native_bf16, resolve_bf16


def test_explicit_values_stay_and_auto_asks_the_machine() -> None:
    assert resolve_bf16(True) is True and resolve_bf16(False) is False
    assert resolve_bf16("auto") is native_bf16("cpu")
    assert native_bf16("mps") is False
    with pytest.raises(ValueError, match="bf16 must be true, false or 'auto', got 'yes'"):
        resolve_bf16("yes")


def test_native_bf16_agrees_with_the_cpu_flags() -> None:
    cpuinfo = Path("/proc/cpuinfo")
    if not cpuinfo.is_file() or "flags" not in cpuinfo.read_text():
        pytest.skip("no /proc/cpuinfo flags on this machine (not Linux x86)")
    flags = set(next(line for line in cpuinfo.read_text().splitlines() if line.startswith("flags")).split())
    assert native_bf16("cpu") == (bool({"avx512_bf16", "amx_bf16"} & flags) and not kernels_capped())


@pytest.mark.parametrize(
    ("isa", "capped"),
    [("AVX2", True), ("avx512_core", True), ("AVX512_CORE_BF16", False), ("AMX", False), ("ALL", False)],
)
def test_kernels_capped_below_bfloat16_are_not_native(monkeypatch: pytest.MonkeyPatch, isa: str, capped: bool) -> None:
    monkeypatch.delenv("ATEN_CPU_CAPABILITY", raising=False)
    monkeypatch.setenv("ONEDNN_MAX_CPU_ISA", isa)
    assert kernels_capped() is capped
    if capped:
        assert native_bf16("cpu") is False


def test_the_module_resolves_auto() -> None:
    from stamlane.models import STAM, LaneDecoder, VGGEncoder
    from stamlane.training.module import StamLaneModule

    module = StamLaneModule(VGGEncoder(width=0.125), STAM, LaneDecoder, bf16="auto")
    assert module.bf16 is native_bf16("cpu") and module.hparams["bf16"] == "auto"


def test_auto_is_asked_again_on_the_device_the_module_is_on(monkeypatch: pytest.MonkeyPatch) -> None:
    """A module built on a CPU without native bf16 and trained on a GPU that has it runs bf16 there (the H200
    check found "auto" resolved once, from the CPU, at construction)."""
    import torch

    from stamlane.models import STAM, LaneDecoder, VGGEncoder
    from stamlane.training import hardware
    from stamlane.training.module import StamLaneModule

    module = StamLaneModule(VGGEncoder(width=0.125), STAM, LaneDecoder, bf16="auto")
    monkeypatch.setattr(hardware, "native_bf16", lambda device_type="cpu": device_type == "cuda")
    assert module.bf16 is False  # on the CPU
    monkeypatch.setattr(type(module), "device", property(lambda self: torch.device("cuda", 0)))
    assert module.bf16 is True
    module.bf16 = False  # an explicit value stays, on every device
    assert module.bf16 is False
