"""The training floor: the Lightning shell around the network and the data.

- `stamlane.training.module`: `StamLaneModule` (the LightningModule), the poly schedule and the paper's SGD;
- `stamlane.training.losses`: `LaneLoss` (segmentation and discriminative embedding losses);
- `stamlane.training.lightning_cli`: `StamLaneCLI`, ``stamlane fit|validate|test|predict``;
- callbacks: `stamlane.training.final_checkpoint`, `stamlane.training.fit_report`, `stamlane.training.resume`,
  `stamlane.training.history_use_monitor` (history use measured during validation);
- `stamlane.training.registry`: the closed registry, what a checkpoint or a run folder may build, and
  `stamlane.training.typed_values`, its checks of a value against a parameter's type hint;
- `stamlane.training.compat`: what older versions wrote (old names, flat data options), read in today's form;
- `stamlane.training.hardware` (native bfloat16), `stamlane.training.quiet` (the libraries' noise),
  `stamlane.training.lightning_compat` (the private Lightning parts used, in one place).

Importing this package imports nothing (``stamlane.training.compat`` and the registry load without Lightning).
"""
