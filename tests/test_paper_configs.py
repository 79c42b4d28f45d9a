"""Every row config of the paper's tables (``configs/paper``) loads with ``stamlane fit``'s parser, composes
with the base configs, and builds a model that runs a clip of the row's number of frames."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
import torch
import yaml

from stamlane.experiments.table_index import load_tables
from stamlane.training.lightning_cli import StamLaneCLI

REPO = Path(__file__).resolve().parents[1]
PAPER = REPO / "configs" / "paper"
INDEX = load_tables(PAPER / "tables.yaml")
ROWS = sorted({r.config for t in INDEX.tables.values() for r in t.rows})
# the real-data bases the README's commands use, where they exist in this checkout
REAL_BASES = [
    p for p in (REPO / "configs" / "tusimple_stam4.yaml", REPO / "configs" / "apollo_stam2.yaml") if p.is_file()
]
torch.set_num_threads(1)


pytestmark = pytest.mark.usefixtures("plain_argv")


def _configs(row: Path, base: Path = INDEX.default_base) -> list[str]:
    return [a for c in (base, *INDEX.layers, row) for a in ("--config", str(c))]


def _expected(row: Path, base_cfg: dict) -> dict:
    """What the row file says (fusion class, its stated init_args, frames, alignment or the base's)."""
    raw = yaml.safe_load(row.read_text())
    fusion = raw["model"]["fusion"]
    return {
        "class_path": fusion["class_path"],
        "init_args": fusion.get("init_args") or {},
        "num_frames": raw["data"]["clip"]["num_frames"],
        "align": raw["data"]["clip"].get("align", ((base_cfg.get("data") or {}).get("clip") or {}).get("align", "fly")),
    }


@pytest.fixture(scope="module")
def cli() -> StamLaneCLI:
    """One StamLaneCLI (run=False) on the first row: its parser is reused for every row."""
    sys.argv = ["stamlane"]
    extra = ["--trainer.logger=false", "--trainer.enable_checkpointing=false", "--trainer.callbacks=[]"]
    return StamLaneCLI(args=[*_configs(ROWS[0]), *extra], run=False)


def test_index_rows_exist_and_are_used() -> None:
    files = sorted((PAPER / "rows").glob("*.yaml"))
    assert files == ROWS, "every row file is listed in tables.yaml and every listed row has a file"
    assert len(ROWS) == 30


def test_print_config_of_a_row(capsys: pytest.CaptureFixture) -> None:
    """``stamlane fit --config demo.yaml --config ablation.yaml --config rows/f4_stdanet.yaml --print_config``."""
    row = PAPER / "rows" / "f4_stdanet.yaml"
    with pytest.raises(SystemExit) as stop:
        StamLaneCLI(args=["fit", *_configs(row), "--print_config"])
    assert stop.value.code in (0, None)
    cfg = yaml.safe_load(capsys.readouterr().out)
    assert cfg["model"]["fusion"] == {"class_path": "stamlane.models.STDANet", "init_args": {"reduction": 8}}
    assert cfg["data"]["clip"]["num_frames"] == 4  # (model.num_frames is linked from it, so not printed)
    assert cfg["model"]["report_run_time"] is False  # the ablation layer
    assert cfg["model"]["encoder"]["init_args"]["width"] == 0.25  # the base


def test_every_row_parses_and_builds_a_working_model(cli: StamLaneCLI) -> None:
    base_cfg = yaml.safe_load(INDEX.default_base.read_text())
    for row in ROWS:
        want = _expected(row, base_cfg)
        cfg = cli.parser.parse_args([*_configs(row), "--trainer.logger=false", "--trainer.callbacks=[]"])
        fusion = cfg.model.fusion
        assert fusion.class_path == want["class_path"], row.name
        for key, value in want["init_args"].items():
            assert fusion.init_args[key] == value, (row.name, key)
        assert cfg.data.clip.num_frames == cfg.model.num_frames == want["num_frames"], row.name
        assert cfg.data.clip.align == want["align"], row.name
        model = cli.parser.instantiate_classes(cfg).model
        assert type(model.net.fusion).__name__ == want["class_path"].rsplit(".", 1)[1], row.name
        model.eval()
        with torch.no_grad():
            logits, embedding = model(torch.rand(1, want["num_frames"], 3, 32, 64))
        assert logits.shape == (1, 2, 32, 64) and embedding.shape[2:] == (32, 64), row.name


@pytest.mark.skipif(not REAL_BASES, reason="configs/tusimple_stam4.yaml / apollo_stam2.yaml not in this checkout")
@pytest.mark.parametrize("base", REAL_BASES, ids=[p.stem for p in REAL_BASES])
def test_rows_compose_with_the_real_data_bases(cli: StamLaneCLI, base: Path) -> None:
    base_cfg = yaml.safe_load(base.read_text())
    for row in ROWS:
        want = _expected(row, base_cfg)
        cfg = cli.parser.parse_args([*_configs(row, base), "--trainer.logger=false", "--trainer.callbacks=[]"])
        assert cfg.model.fusion.class_path == want["class_path"], row.name
        assert cfg.data.clip.num_frames == cfg.model.num_frames == want["num_frames"], row.name
        if "align" in yaml.safe_load(row.read_text())["data"]["clip"]:
            assert cfg.data.clip.align == "none", row.name
