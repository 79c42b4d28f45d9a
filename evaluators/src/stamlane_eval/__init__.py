"""stamlane-eval: TuSimple, CULane/ApolloScape and video lane metrics, number for number equal to the official tools.

The core (``tusimple``, ``culane``, ``video``, ``temporal``, ``io``, ``cli``) needs numpy/scipy/opencv only; the
torchmetrics metrics and the Lightning callback live in ``stamlane_eval.integrations`` and are imported only on
request.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("stamlane-eval")  # written once, in evaluators/pyproject.toml
except PackageNotFoundError:  # a source tree that was never installed
    __version__ = "unknown"
