"""The paper's ablation tables as rows of configs: reading ``configs/paper/tables.yaml``.

The index names, per table, its rows (a row = a config file ``rows/<id>.yaml`` holding only what defines
the row), the label printed for it and the paper's numbers; ``default_base`` and ``layers`` name the
configs every run starts from (paths relative to the index file). See the index file's header.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import yaml
from stamlane_eval import names

from stamlane.configs import configs_dir

__all__ = [
    "METRIC_KINDS",
    "PaperRow",
    "PaperTable",
    "TableIndex",
    "baseline_pairs",
    "default_index_path",
    "load_tables",
    "paper_column_name",
]

METRIC_KINDS = ("tusimple", "iou")
"""``tusimple``: accuracy / FP / FN / F1 (TuSimple protocol); ``iou``: precision / recall / F1 at IoU
thresholds (CULane area metric, the paper's ApolloScape tables)."""

_METRIC = {"tusimple": names.TUSIMPLE, "iou": names.CULANE}
"""The evaluator metric of each kind (the index's ``iou`` is the CULane area metric)."""


def paper_column_name(kind: str, short: str) -> str:
    """The name `LaneEvalCallback` logs (after ``test/``) for a paper column (`stamlane_eval.names`):
    ``("iou", "f1@0.5")`` -> ``"culane_f1@0.5"``, ``("tusimple", "fp")`` -> ``"tusimple_fp"``.

    Raises:
        ValueError: an unknown kind, or a column its metric does not give.
    """
    if kind not in _METRIC:
        raise ValueError(f"metric kind must be one of {METRIC_KINDS}, got {kind!r}")
    return names.metric_name(_METRIC[kind], *names.parse_metric_key(short))


@dataclass(frozen=True)
class PaperRow:
    """One row of a paper table.

    Attributes:
        id: row id = stem of its config ``rows/<id>.yaml``; runs are stored (and shared) under it.
        label: the row's text in our tables.
        config: path of the row's config file.
        paper: the paper's numbers for the row, as logged metric names (``tusimple_f1``, ``culane_f1@0.5``)
            -> fractions.
    """

    id: str
    label: str
    config: Path
    paper: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class PaperTable:
    """A paper table: number (``"1"``), title, metric kind, rows in the paper's order and, where the paper measures
    the other rows from one of them, that row's id (``baseline``: Tables 2 and 8, unaligned frames summed)."""

    name: str
    title: str
    kind: str
    rows: tuple[PaperRow, ...]
    baseline: str | None = None

    @property
    def f1_key(self) -> str:
        """The headline metric: TuSimple's paper F1, or the IoU F1 at 0.5."""
        return paper_column_name(self.kind, "f1") if self.kind == "tusimple" else paper_column_name(self.kind, "f1@0.5")

    def select(self, ids: list[str] | None) -> tuple[PaperRow, ...]:
        """The rows named by ``ids`` (all when None), in the table's order.

        Raises:
            ValueError: an id that is not a row of this table.
        """
        if not ids:
            return self.rows
        known = {r.id for r in self.rows}
        unknown = [i for i in ids if i not in known]
        if unknown:
            raise ValueError(f"table {self.name} has no row {unknown[0]!r}; its rows: {', '.join(sorted(known))}")
        return tuple(r for r in self.rows if r.id in ids)


@dataclass(frozen=True)
class TableIndex:
    """The parsed index: tables by number, the default base config and the shared layers."""

    path: Path
    default_base: Path
    layers: tuple[Path, ...]
    tables: dict[str, PaperTable]

    def table(self, name: str) -> PaperTable:
        """Table ``name`` (``"1"``, ``"7"``, ...). Raises ValueError for an unknown one."""
        if name not in self.tables:
            raise ValueError(f"no table {name!r} in {self.path}; tables: {', '.join(self.tables)}")
        return self.tables[name]


def default_index_path() -> Path:
    """stamlane's ``configs/paper/tables.yaml`` (`stamlane.configs.configs_dir`), installed or in a checkout."""
    index: Path = configs_dir() / "paper" / "tables.yaml"
    return index


def load_tables(path: str | Path | None = None) -> TableIndex:
    """Read and check the table index.

    Args:
        path: the index yaml; None for `default_index_path`.

    Returns:
        the index, with every config path resolved and checked to exist.

    Raises:
        FileNotFoundError: the index or a config it names is missing.
        ValueError: a malformed index (missing keys, unknown metric kind, duplicate rows in a table).
    """
    path = Path(path) if path is not None else default_index_path()
    if not path.is_file():
        raise FileNotFoundError(f"table index {path} not found")
    from stamlane.safety.budget import MAX_RECORD_BYTES
    from stamlane.safety.guard import read_input

    try:  # plain YAML: a !!python tag is refused, never run
        raw = yaml.safe_load(read_input(path, MAX_RECORD_BYTES, "table index"))
    except yaml.YAMLError as err:
        raise ValueError(f"{path}: not a plain YAML table index ({str(err).splitlines()[0]})") from None
    if not isinstance(raw, dict) or not isinstance(raw.get("tables"), dict):
        raise ValueError(f"{path}: expected a mapping with a 'tables' mapping")
    here = path.parent

    def existing(rel: object) -> Path:
        if not isinstance(rel, str):
            raise ValueError(f"{path}: a config path must be a string, got {rel!r}")
        p = (here / rel).resolve()
        if not p.is_file():
            raise FileNotFoundError(f"{path}: config {rel!r} not found at {p}")
        return p

    default_base = existing(raw.get("default_base", "../demo.yaml"))
    layers_given = raw.get("layers", [])
    if not isinstance(layers_given, list):
        raise ValueError(f"{path}: layers must be a list of config paths, got {layers_given!r}")
    layers = tuple(existing(p) for p in layers_given)
    tables: dict[str, PaperTable] = {}
    for name, spec in raw["tables"].items():
        name = str(name)
        if not isinstance(spec, dict) or not isinstance(spec.get("rows", []), list):
            raise ValueError(f"{path}: table {name} must be a mapping with a list of rows")
        kind = spec.get("metrics")
        if kind not in METRIC_KINDS:
            raise ValueError(f"{path}: table {name}: metrics must be one of {METRIC_KINDS}, got {kind!r}")
        rows = []
        for r in spec.get("rows", []):
            if not isinstance(r, dict) or not isinstance(r.get("paper") or {}, dict):
                raise ValueError(f"{path}: table {name}: a row must be a mapping (id, label, paper), got {r!r}")
            if "id" not in r:
                raise ValueError(f"{path}: table {name}: a row without 'id': {r!r}")
            given = r.get("paper") or {}
            if any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in given.values()):
                raise ValueError(f"{path}: table {name}: row {r['id']!r}: paper values must be numbers")
            try:
                paper = {paper_column_name(kind, str(k)): float(v) for k, v in given.items()}
            except ValueError as err:
                raise ValueError(f"{path}: table {name}: row {r['id']!r}: paper column: {err}") from None
            rows.append(PaperRow(str(r["id"]), str(r.get("label", r["id"])), existing(f"rows/{r['id']}.yaml"), paper))
        ids = [r.id for r in rows]
        if len(set(ids)) != len(ids) or not ids:
            raise ValueError(f"{path}: table {name}: rows must be unique and non-empty, got {ids}")
        baseline = spec.get("baseline")
        if baseline is not None and baseline not in ids:
            raise ValueError(f"{path}: table {name}: baseline {baseline!r} is not one of its rows")
        tables[name] = PaperTable(name, str(spec.get("title", f"Table {name}")), kind, tuple(rows), baseline)
    return TableIndex(path.resolve(), default_base, layers, tables)


def baseline_pairs(models: dict[str, str], index: TableIndex | None = None) -> list[tuple[str, str]]:
    """``(model, baseline model)`` for every row of a table with a ``baseline`` (Tables 2 and 8: unaligned frames
    summed) whose row and baseline are both among ``models`` (paper row id -> model name)."""
    found = []
    for table in (index or load_tables()).tables.values():
        base = models.get(table.baseline) if table.baseline is not None else None
        found += [(models[r.id], base) for r in table.rows if base and models.get(r.id, base) != base]
    return list(dict.fromkeys(found))
