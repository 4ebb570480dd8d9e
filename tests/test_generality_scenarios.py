"""The held-out scenarios of tools/generality/: what a new user does first with a file they
wrote, `rgmcad check` it and `rgmcad simulate` its hand-found layout, must work for each."""

import dataclasses
import json
from pathlib import Path

import pytest

from rgmcad.cli import main
from rgmcad.parts.family import load_families

HELD_OUT = sorted(Path("tools/generality").glob("*.toml"))


def test_the_held_out_set_is_there():
    # An empty glob would leave the tests below with nothing to check.
    assert len(HELD_OUT) >= 3


@pytest.mark.parametrize("path", HELD_OUT, ids=lambda p: p.stem)
def test_check_accepts_the_file_and_its_hand_layout(path, capsys):
    assert main(["check", str(path)]) == 0
    out = capsys.readouterr().out
    assert "hand: valid, inside the design space" in out


@pytest.mark.parametrize("path", HELD_OUT, ids=lambda p: p.stem)
def test_hand_layout_succeeds(path, capsys):
    assert main(["simulate", str(path), "--layout", "hand", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["outcome"] == "success"
    assert all(e["state"] == "success" for e in out["events"])
    # Held-out scenarios stay cheap enough to optimise: a few seconds simulated, tens of
    # events at most.
    assert out["sim_time"] < 5.0


def test_the_held_out_set_has_big_machines():
    # Issue 50: at least two machines of 25 to 40 free parameters and 20 or more events, each
    # with a hand layout (checked above with the rest), for the method to prove itself on.
    from rgmcad.scene.loader import load_scenario

    big = {path.stem: load_scenario(path) for path in HELD_OUT}
    big = {name: s for name, s in big.items() if 25 <= s.dimension <= 40}
    assert {"grand_course", "lever_arc"} <= set(big)
    for name, scenario in big.items():
        assert len(scenario.events) >= 20, name
        assert "hand" in scenario.layouts, name


def test_the_documentation_lists_every_part_family_with_its_parameters():
    # A new user writes a scenario from the documentation's page of families (the reference's
    # Part families, generated from parts/*.py), not from parts/*.py.
    from rgmcad.reference import parts as parts_page

    page = parts_page.page()
    sections = {part.split("`")[0]: part for part in page.split("\n## `")[1:]}
    families = load_families()
    assert sorted(sections) == sorted(families)
    for name, family in families.items():
        for field in dataclasses.fields(family.params):
            assert f"`{field.name}`" in sections[name], f"{name}: {field.name} missing"
