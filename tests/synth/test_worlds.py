"""Worlds as parts (`stamlane.synth.worlds`, `stamlane.synth.parts`): every world is a choice of each part's variants,
every variant is implemented, a new world is one entry that draws without a branch of its own, and the modules of
the generator import one another without a circle."""

from __future__ import annotations

import ast
import json
from dataclasses import fields, replace
from pathlib import Path

import numpy as np
import pytest

import stamlane.synth
from stamlane.synth.cli import build_parser
from stamlane.synth.clip import generate_clip
from stamlane.synth.config import SynthConfig
from stamlane.synth.parts import IMPLEMENTED, Parts
from stamlane.synth.worlds import PART_VARIANTS, WORLDS, World

SMALL = SynthConfig(width=160, height=90, num_frames=3, occluder_prob=1.0)


def test_every_part_variant_a_world_can_pick_is_implemented_and_nothing_else():
    assert IMPLEMENTED == {part: tuple(variants) for part, variants in PART_VARIANTS.items()}
    assert [f.name for f in fields(World)][1:] == list(PART_VARIANTS) == [f.name for f in fields(Parts)]


def test_every_world_resolves_to_its_parts_and_the_settings_and_the_command_take_it():
    choices = next(a for a in build_parser()._actions if "--world" in a.option_strings).choices
    assert tuple(choices) == tuple(WORLDS)
    for name, world in WORLDS.items():
        parts = Parts.of(world)
        assert SynthConfig(world=name).world == name and parts.camera is not None
    with pytest.raises(ValueError, match="world must be one of \\('classic', 'dashcam', 'dashcam2', 'dashcam3'\\)"):
        SynthConfig(world="moon")


def test_a_world_refuses_a_variant_no_part_has():
    with pytest.raises(ValueError, match="a world's verges must be one of \\('grass', 'kinds'\\), got 'snow'"):
        World("snowy", verges="snow")  # type: ignore[arg-type]


def test_the_worlds_are_the_compositions_their_formats_made():
    dashcam, dashcam2, dashcam3 = WORLDS["dashcam"], WORLDS["dashcam2"], WORLDS["dashcam3"]
    assert WORLDS["classic"] == World(WORLDS["classic"].description)  # every part's first variant
    assert replace(dashcam2, description="") == replace(
        dashcam, description="", surface="repaired", lights="sun", furniture="curbs_poles", vehicles="bodies"
    )
    assert replace(dashcam3, description="") == replace(dashcam2, description="", verges="kinds")
    assert [n for n, w in WORLDS.items() if w.randomisable] == ["dashcam", "dashcam2", "dashcam3"]


def test_the_classic_parts_draw_nothing_before_the_road():
    rng = np.random.default_rng(5)
    before = json.dumps(rng.bit_generator.state)
    look = Parts.of(WORLDS["classic"]).look(rng, SMALL)
    assert json.dumps(rng.bit_generator.state) == before
    assert look.config == SMALL and look.marking is None and look.sensor is None


def test_a_new_world_is_one_entry_and_draws_what_its_parts_draw(monkeypatch: pytest.MonkeyPatch):
    # the classic world with dashcam3's verges: the verges draw last before the texture, so the road, the drive and
    # the labels are the classic world's, the frames are not
    monkeypatch.setitem(WORLDS, "verged", World("the classic world on dirt and gravel", verges="kinds"))
    verged = generate_clip(replace(SMALL, world="verged"), np.random.default_rng(4))
    classic = generate_clip(SMALL, np.random.default_rng(4))
    assert verged.labels == classic.labels and verged.h_samples == classic.h_samples
    assert not np.array_equal(verged.frames[-1], classic.frames[-1])
    # a composition no format made: a dashcam camera on a city street (curbs and poles, no barriers, the sun)
    street = World("street", camera="dashcam", lights="sun", furniture="curbs_poles", vehicles="bodies")
    monkeypatch.setitem(WORLDS, "street", street)
    a = generate_clip(replace(SMALL, world="street"), np.random.default_rng(4))
    b = generate_clip(replace(SMALL, world="street"), np.random.default_rng(4))
    assert all(np.array_equal(x, y) for x, y in zip(a.frames, b.frames)) and a.labels == b.labels
    assert a.h_samples != classic.h_samples  # the dashcam camera's horizon
    with pytest.raises(ValueError, match="randomise"):  # its sensor is none: nothing to randomise
        SynthConfig(world="street", randomise=True)


def _synth_imports() -> dict[str, set[str]]:
    """Every module of stamlane.synth and the modules of stamlane.synth it imports anywhere (at the top, under
    TYPE_CHECKING, inside a function)."""
    folder = Path(stamlane.synth.__file__).parent
    graph = {}
    for path in sorted(folder.glob("*.py")):
        name = "stamlane.synth" if path.stem == "__init__" else f"stamlane.synth.{path.stem}"
        deps = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("stamlane.synth"):
                if node.module == "stamlane.synth":  # from stamlane.synth import clip, ...
                    deps |= {f"stamlane.synth.{a.name}" for a in node.names}
                else:
                    deps.add(node.module)
            elif isinstance(node, ast.Import):
                deps |= {a.name for a in node.names if a.name.startswith("stamlane.synth.")}
        graph[name] = deps - {name}
    return graph


def test_the_generator_modules_import_one_another_without_a_circle():
    graph = _synth_imports()
    assert graph["stamlane.synth.clip"] >= {"stamlane.synth.parts", "stamlane.synth.worlds"}  # the walk sees edges
    done: set[str] = set()

    def visit(name: str, path: tuple[str, ...]) -> None:
        assert name not in path, f"an import circle: {' -> '.join((*path[path.index(name) :], name))}"
        if name in done:
            return
        for dep in sorted(graph.get(name, ())):
            visit(dep, (*path, name))
        done.add(name)

    for name in sorted(graph):
        if name != "stamlane.synth":  # the package's lazy names point down at its modules, which it is above
            visit(name, ())
