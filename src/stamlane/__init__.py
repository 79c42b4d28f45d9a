"""stamlane: lane mark detection with pre-aligned spatial-temporal attention (Chen & Xiang, Sensors 2022)."""

__all__ = ["__version__"]


def __getattr__(name: str) -> str:
    """``__version__``, read from the installed distribution on first use: the version is written once, in
    pyproject.toml (``stamlane --version`` and the metadata of an exported .onnx read it here)."""
    if name != "__version__":
        raise AttributeError(f"module 'stamlane' has no attribute {name!r}")
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("stamlane")
    except PackageNotFoundError:  # a source tree that was never installed
        return "unknown (not installed)"
