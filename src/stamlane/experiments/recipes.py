"""What an experiment trains: rows (the models), and recipes (how every row is trained, in one or two stages).

A recipe's optional stage 1 trains a single-frame network from scratch whose final weights start every row; its
stage 2 (or its only stage) trains each row. Each stage has its steps and its ``stamlane fit`` arguments
(`Stage`), as data: options keyed by their dotted names (``{"data.augment.key_corruption": 0.5}``,
`stamlane.training.runs.RunSpec`); `stamlane.experiments.runner.Runner.train` trains one row from one stage.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from stamlane.configs import configs_dir
from stamlane.experiments.store import ExperimentError
from stamlane.training.runs import flags_of

__all__ = ["CONFIG_DIR", "KEY_CORRUPTION", "PRETRAIN", "RECIPES", "Recipe", "Row", "Stage"]

CONFIG_DIR = configs_dir()


@dataclass(frozen=True)
class Row:
    """A model of an experiment: a name (its folders), a label (its tables), its ``stamlane fit`` configs
    (relative to ``configs/``, in order), the paper row it is (``configs/paper/tables.yaml``), if any, and whether
    the recipe's ``row_args`` (the key-frame corruption of the CPU recipe) apply to it."""

    name: str
    label: str
    configs: tuple[str, ...]
    paper: str | None = None
    recipe_args: bool = True

    @classmethod
    def paper_row(cls, row: str, base: str = "demo.yaml") -> Row:
        """A row of the paper's tables on ``base`` (``base``, ``paper/ablation.yaml``, ``paper/rows/<row>.yaml``)."""
        if not (CONFIG_DIR / "paper" / "rows" / f"{row}.yaml").is_file():
            known = sorted(p.stem for p in (CONFIG_DIR / "paper" / "rows").glob("*.yaml"))
            raise ExperimentError(f"no paper row {row!r}; known rows: {' '.join(known)}")
        return cls(row, f"paper row {row}", (base, "paper/ablation.yaml", f"paper/rows/{row}.yaml"), paper=row)


@dataclass(frozen=True)
class Stage:
    """One training of a recipe.

    Attributes:
        steps: training steps.
        overrides: options over the row's configs (dotted names: `stamlane.training.runs.RunSpec`).
        val_checks: validations over the run (they draw the curves; every score is of the final weights).
        val_batches: validation batches each validation scores (None: the whole split).
    """

    steps: int
    overrides: Mapping[str, Any] = field(default_factory=dict)
    val_checks: int = 4
    val_batches: int | None = None

    def val_every(self) -> int:
        """Steps between two validations."""
        return max(1, self.steps // max(self.val_checks, 1))


@dataclass(frozen=True)
class Recipe:
    """How every row is trained.

    Attributes:
        name: ``"cpu"`` (two stages), ``"paper"`` (one stage), or a benchmark's own.
        steps: steps of each row (stage 2 of the two-stage recipe).
        pretrain_steps: steps of stage 1, the single-frame network from scratch whose final weights start every
            row (0: one stage, every row from scratch).
        pretrain: the stage-1 model.
        row_overrides: options of every row's training (not of stage 1), over its configs; recorded as the
            ``stamlane fit`` flags they are (``row_args``, `settings`, `stamlane.training.runs.flags_of`), as
            records always held them (those of before read the same: `stamlane.experiments.store.upgrade_record`).
        pretrain_overrides: options of stage 1, over its configs (recorded as ``pretrain_args``).
        val_checks: validations per run (for the curves; stage 2 validates half as often as stage 1).
        val_batches: validation batches each validation scores (None: the whole split). The validations only draw
            the curves (every score is of the final weights, on the test splits); how many batches they read
            leaves the final weights bit for bit the same (tests/experiments/test_engine_speed.py).
        description: what the recipe is for (printed by the benchmarks that compare recipes).
    """

    name: str
    steps: int
    pretrain_steps: int = 0
    pretrain: Row | None = None
    row_overrides: Mapping[str, Any] = field(default_factory=dict)
    pretrain_overrides: Mapping[str, Any] = field(default_factory=dict)
    val_checks: int = 4
    val_batches: int | None = None
    description: str = ""

    def pretraining(self) -> Stage | None:
        """Stage 1, or None for a one-stage recipe."""
        if self.pretrain is None:
            return None
        return Stage(self.pretrain_steps, self.pretrain_overrides, self.val_checks, self.val_batches)

    def training(self, row: Row) -> Stage:
        """The stage that trains ``row``: stage 2 of two (validated half as often), or the only one; the recipe's
        ``row_overrides`` where the row takes them."""
        checks = self.val_checks // 2 if self.pretrain is not None else self.val_checks
        return Stage(self.steps, self.row_overrides if row.recipe_args else {}, checks, self.val_batches)

    def settings(self) -> dict[str, Any]:
        """What every run trained by the recipe records (`stamlane.experiments.store.RunStore.finished`): the options
        as the ``stamlane fit`` flags they are, so that the records of before are the same runs."""
        return {
            "recipe": self.name,
            "pretrain_steps": self.pretrain_steps,
            "steps": self.steps,
            "row_args": flags_of(self.row_overrides),
            "pretrain_args": flags_of(self.pretrain_overrides),
        }


PRETRAIN = Row("pretrain", "1 frame, stage 1 (every model starts here)", ("demo_single.yaml",))
KEY_CORRUPTION = {"data.augment.key_corruption": 0.5, "data.augment.key_corruption_kinds": ["blank", "glare"]}
"""Stage 2 of the CPU recipe: half the training clips have their key frame's near road blanked or the frame
overexposed, history intact (`stamlane.data.corruption`): the reason to read the history (docs/training.md)."""
RECIPES = {
    "cpu": Recipe(
        "cpu", steps=300, pretrain_steps=1200, pretrain=PRETRAIN, row_overrides=KEY_CORRUPTION, val_batches=25
    ),
    "paper": Recipe("paper", steps=1500),
}
"""The named recipes (docs/training.md): ``cpu``, the demo's two stages (1,200 single-frame steps from scratch,
then each row for 300 steps from those weights with the key frame corrupted in half the clips: every model gets
1,500 steps on the same data; the validations of the curves on 25 batches, 100 clips); ``paper``, every row from
scratch for 1,500 steps (the paper's protocol at a CPU budget). Steps can be changed per call."""
