"""stamlane-eval: TuSimple, CULane/ApolloScape and video lane metrics, number for number equal to the official tools.

The core (``tusimple``, ``culane``, ``video``, ``temporal``, ``io``, ``cli``) needs numpy/scipy/opencv only; the
torchmetrics metrics and the Lightning callback live in ``stamlane_eval.integrations`` and are imported only on
request.
"""

__all__ = ["__version__"]


def __getattr__(name: str) -> str:
    """``__version__``, read from the installed distribution on first use (importlib.metadata's cost, which every
    ``stamlane-eval`` run would pay: docs/results/evaluators/)."""
    if name != "__version__":
        raise AttributeError(f"module 'stamlane_eval' has no attribute {name!r}")
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("stamlane-eval")  # written once, in evaluators/pyproject.toml
    except PackageNotFoundError:  # a source tree that was never installed
        return "unknown"
