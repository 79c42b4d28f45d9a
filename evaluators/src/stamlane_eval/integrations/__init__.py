"""Optional integrations (need the ``torch`` extra): torchmetrics metrics and a Lightning callback.

Import the submodules explicitly: ``stamlane_eval.integrations.torchmetrics`` and
``stamlane_eval.integrations.lightning``.
"""
