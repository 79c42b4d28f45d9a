"""Experiments: train rows x seeds, score them with intervals, probe their history, report (one engine).

- `stamlane.experiments.engine`: rows, named recipes, the `Experiment` (train, predict, score, summarise);
- `stamlane.experiments.store`: run folders, the resume lock (``done.json``) and the atomic writer;
- `stamlane.experiments.scoring`: a predictions file scored in every metric, per image;
- `stamlane.experiments.metrics`: the metrics, one name each (the callback's);
- `stamlane.experiments.history`: paint visibility: recall per class, the oracle headroom;
- `stamlane.experiments.stats`: values and differences with intervals over clips and seeds;
- `stamlane.experiments.summary`: the typed ``summary.json`` (older summaries read through ``legacy``);
- `stamlane.experiments.report`: markdown tables, the paper's tables, csv, plots (``stamlane report``);
- `stamlane.experiments.tables`: the paper's table index (``configs/paper/tables.yaml``);
- `stamlane.experiments.ablate`: ``stamlane ablate``, the engine on the paper's tables.
"""

from stamlane.experiments.summary import Summary
from stamlane.experiments.tables import PaperRow, PaperTable, TableIndex, load_tables

__all__ = ["PaperRow", "PaperTable", "Summary", "TableIndex", "load_tables"]
