"""stamlane-eval stands alone: its core imports without torch, and no module imports stamlane."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import stamlane_eval

SRC = Path(stamlane_eval.__file__).parent


def test_core_imports_and_runs_with_torch_blocked() -> None:
    golden = Path(__file__).parent / "golden"
    code = (
        "import sys\n"
        "for m in ('torch', 'torchmetrics', 'lightning', 'stamlane'):\n"
        "    sys.modules[m] = None\n"
        "import stamlane_eval.tusimple, stamlane_eval.culane, stamlane_eval.io, stamlane_eval.cli, stamlane_eval.video\n"
        f"code = stamlane_eval.cli.main(['tusimple', r'{golden / 'tusimple_pred.json'}', r'{golden / 'tusimple_gt.json'}', '--json'])\n"
        "assert code == 0, code\n"
        "assert not any(m.startswith(('torch', 'lightning')) and sys.modules[m] is not None for m in sys.modules)\n"
        "assert 'cv2' not in sys.modules and 'scipy' not in sys.modules, 'the TuSimple path imports cv2 or scipy'\n"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    assert '"accuracy"' in res.stdout


def _imports(path: Path) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module.split(".")[0])
    return names


def test_dependency_direction() -> None:
    for path in SRC.rglob("*.py"):
        mods = _imports(path)
        assert "stamlane" not in mods, path
        if "integrations" not in path.parts:
            assert not mods & {"torch", "torchmetrics", "lightning"}, path
