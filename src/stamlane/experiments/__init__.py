"""Experiments: the paper's ablation tables as configs (``configs/paper``) and ``stamlane ablate``.

- `stamlane.experiments.tables`: the table index (rows, labels, the paper's numbers);
- `stamlane.experiments.runner`: one run (a row, a seed) through ``StamLaneCLI`` in this process;
- `stamlane.experiments.results`: per-run ``result.json`` and mean ± std over seeds;
- `stamlane.experiments.report`: CSV, markdown, robustness split (Table 6) and bar plot;
- `stamlane.experiments.ablate`: the command (``main(argv) -> int``).
"""

from stamlane.experiments.results import RowSummary, summarize
from stamlane.experiments.tables import PaperRow, PaperTable, TableIndex, load_tables

__all__ = ["PaperRow", "PaperTable", "RowSummary", "TableIndex", "load_tables", "summarize"]
