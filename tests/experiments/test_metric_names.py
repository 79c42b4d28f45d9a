"""The experiments name their numbers with the evaluators' names (`stamlane_eval.names`): the metrics, the paper
tables (whose index says ``iou`` for the CULane area metric) and the report read one vocabulary."""

from __future__ import annotations

from pathlib import Path

import pytest
from stamlane_eval.names import metric_name, parse_metric_name

from stamlane.experiments.metrics import CLASS_RECALL, CULANE_F1, REPORTED, TEMPORAL_STABILITY, TUSIMPLE_F1
from stamlane.experiments.table_index import load_tables, paper_column_name


def test_every_evaluator_metric_an_experiment_reports_has_its_callback_name() -> None:
    assert TUSIMPLE_F1.key == "tusimple_f1" and [m.key for m in CULANE_F1] == ["culane_f1@0.5", "culane_f1@0.3"]
    assert [m.key for m in TEMPORAL_STABILITY][:3] == ["temporal_rs@0.5", "temporal_rj@0.5", "temporal_rm@0.5"]
    for m in REPORTED:
        if m in CLASS_RECALL:  # stamlane's own numbers (recall per visibility class): no evaluator logs them
            with pytest.raises(ValueError):
                parse_metric_name(m.key)
            continue
        assert str(parse_metric_name(m.key)) == m.key


def test_paper_columns_are_named_by_the_one_builder() -> None:
    assert paper_column_name("iou", "f1@0.5") == metric_name("culane", "f1", 0.5) == "culane_f1@0.5"
    assert paper_column_name("iou", "precision@0.3") == "culane_precision@0.3"
    assert paper_column_name("tusimple", "fp") == metric_name("tusimple", "fp") == "tusimple_fp"
    with pytest.raises(ValueError, match="metric kind"):
        paper_column_name("culane", "f1@0.5")  # the index's word for the area metric is "iou"
    with pytest.raises(ValueError, match="per IoU threshold"):
        paper_column_name("iou", "f1")
    index = load_tables()
    for table in index.tables.values():
        assert parse_metric_name(table.f1_key).quantity == "f1"
        for row in table.rows:
            for key in row.paper:
                assert str(parse_metric_name(key)) == key


def test_an_index_naming_a_column_no_metric_gives_is_refused(tmp_path: Path) -> None:
    repo = Path(__file__).resolve().parents[2]
    (tmp_path / "rows").mkdir()
    (tmp_path / "rows" / "f1_keyonly.yaml").write_text((repo / "configs/paper/rows/f1_keyonly.yaml").read_text())
    (tmp_path / "tables.yaml").write_text(
        f"default_base: {repo / 'configs' / 'demo.yaml'}\n"
        "tables:\n"
        "  '9':\n"
        "    metrics: iou\n"
        "    rows:\n"
        "      - {id: f1_keyonly, paper: {f1@0.5: 0.9, accuracy: 0.9}}\n"
    )
    with pytest.raises(ValueError, match=r"table 9: row 'f1_keyonly': paper column: culane gives no 'accuracy'"):
        load_tables(tmp_path / "tables.yaml")
