"""Experiments: train rows x seeds, score them with intervals, probe their history, report (one runner).

- `stamlane.experiments.recipes`: rows (the models) and named recipes (one or two training stages);
- `stamlane.experiments.store`: the run store: the layout of an experiment's folder and the runs' records
  (``done.json``, the resume lock);
- `stamlane.experiments.runner`: `Runner.train` (one run of a row from a recipe stage) and `Runner.score` (a run
  predicted and scored on splits with its history probes);
- `stamlane.experiments.engine`: the `Experiment`: rows x seeds trained, scored, probed and summarised;
- `stamlane.experiments.split_scores`: a split's predictions file scored in every metric, per image (and the recall per
  paint-visibility class);
- `stamlane.experiments.metrics`: the metrics, one name each (the callback's);
- `stamlane.experiments.oracles`: the oracles of the labels (what history can reveal: the headroom);
- `stamlane.experiments.intervals`: values and differences of runs with intervals over clips and seeds (one image is
  scored by `stamlane.predict.image_score`, a split by `split_scores`, a set of runs here);
- `stamlane.experiments.summary`: the typed ``summary.json``;
- `stamlane.experiments.tables` (markdown tables and csv of one summary), `stamlane.experiments.paper_report`
  (the paper's tables, replication), `stamlane.experiments.plots` (the pictures): what ``stamlane report`` writes;
- `stamlane.experiments.table_index`: the paper's table index (``configs/paper/tables.yaml``);
- `stamlane.experiments.workspace`: the data, precision and output folder ``demo`` and ``ablate`` set up;
- `stamlane.experiments.demo`, `stamlane.experiments.ablate`: ``stamlane demo`` and ``stamlane ablate``.
"""

from stamlane.experiments.summary import Summary
from stamlane.experiments.table_index import PaperRow, PaperTable, TableIndex, load_tables

__all__ = ["PaperRow", "PaperTable", "Summary", "TableIndex", "load_tables"]
