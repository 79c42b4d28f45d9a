"""stamlane-eval: TuSimple and CULane/ApolloScape lane metrics, number for number equal to the official tools.

The core (``tusimple``, ``culane``, ``io``, ``cli``) needs numpy/scipy/opencv only; the torchmetrics metrics
and the Lightning callback live in ``stamlane_eval.integrations`` and are imported only on request.
"""

__version__ = "0.1.0"
