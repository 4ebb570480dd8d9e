"""Hostile scenario files, handed to ``rgmcad check`` as a user would: each is refused in one
line on stderr naming the file and the key, with exit status 2, within seconds, with no
traceback, no Python warning and no control character reaching the terminal.

Five classes, each with a corpus generated from a fixed seed besides the cases a hostile user
reported: files far larger than their limit (sparse, costing no disk), SVG drawings whose
reading would take minutes (segments, closings, <use> copies, nesting, entities, transforms,
style sheets), domino runs whose dominoes stand inside each other, coordinates near the
largest float, and control characters in text a file supplies. The time bound is a guard
against hangs, not a benchmark: every case takes well under a second.
"""

from __future__ import annotations

import os
import random
import re
import sys
import time
import warnings

import pytest
from _support import cli_output

from rgmcad.errors import ScenarioError, printable
from rgmcad.scene.layout_files import resolve_layout
from rgmcad.scene.loader import load_scenario
from rgmcad.scene.schema import (
    MAX_FILE_BYTES,
    MAX_RUN_OVERLAPS,
    MAX_SVG_BYTES,
    MAX_SVG_CLOSES,
    MAX_SVG_DEPTH,
    MAX_SVG_ELEMENTS,
    MAX_SVG_LENGTH,
    MAX_SVG_NUMBERS,
)

SEED = 20261207
HANG = 5.0  # s: a refusal later than this is a hang
CONTROLS = [chr(c) for c in (*range(0x20), 0x7F, *range(0x80, 0xA0))]
RAW_CONTROL = re.compile("[\x00-\x09\x0b-\x1f\x7f-\x9f]")  # a newline ends a line: counted apart
DOMINO = "{ thickness = 0.007, width = 0.02, height = 0.044 }"
THICKNESS = 0.007
HEAD = ('<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink" '
        'width="300mm" height="200mm" viewBox="0 0 300 200">')
GOOD_PATH = '<path d="M 0 0 L 100 0"/>'


def scenario_text(path="{ kind = \"line\", count = 3, length = 0.03 }", *, description=None,
                  top="") -> str:
    """A scenario of one run along ``path``; ``top``: lines before its first table."""
    text = 'name = "hostile"\n'
    if description is not None:
        text += f'description = "{description}"\n'
    return text + top + f'''[simulation]
duration = 1.0
[runs.run]
domino = {DOMINO}
path = {path}
mass = 0.003
[events.e]
type = "toppling"
body = "run[0]"
angle = 45
'''


def svg_scenario(tmp_path, svg: str | bytes, extra="spacing = 0.02", name="drawn.svg"):
    """A scenario whose run follows the drawing ``svg`` (written beside it)."""
    data = svg.encode() if isinstance(svg, str) else svg
    (tmp_path / name).write_bytes(data)
    path = tmp_path / "drawn.toml"
    path.write_text(scenario_text(f'{{ kind = "svg", file = "{name}", {extra} }}'))
    return path


def check(path) -> tuple[int, str, str, float, list]:
    """``rgmcad check PATH``: exit status, stdout, stderr, seconds, warnings raised."""
    start = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        code, out, err = cli_output(["check", str(path)])
    return code, out, err, time.perf_counter() - start, list(caught)


def refused(path, key: str, *words: str) -> str:
    """The one line ``rgmcad check PATH`` refuses the file with, checked: status 2, one line
    naming the file and then ``key`` (or a key that starts so) and holding ``words``, no
    traceback, no warning, no control
    character, within :data:`HANG` seconds."""
    code, _, err, took, caught = check(path)
    lines = err.splitlines()
    assert code == 2, err[-600:]
    assert len(lines) == 1 and "Traceback" not in err, err[-600:]
    line = lines[0]
    assert line.startswith(f"rgmcad: error: {printable(str(path))}: {key}"), line
    for word in words:
        assert word in line, line
    assert not RAW_CONTROL.search(line), line
    assert not caught, [str(w.message) for w in caught]
    assert took < HANG, f"{took:.1f} s: {line}"
    return line


def sparse(path, size: int):
    with open(path, "wb") as f:
        f.truncate(size)  # a hole: no disk used, whatever the size
    return path


# --- 1. files far larger than their limit: refused by their size, before a byte is read -------

_rng = random.Random(SEED)
HUGE_SVG = [MAX_SVG_BYTES + 1, 50 * 2**30, *(_rng.randint(MAX_SVG_BYTES + 2, 2**36)
                                            for _ in range(5))]
HUGE_SCENARIO = [MAX_FILE_BYTES + 1, 50 * 2**30, *(_rng.randint(MAX_FILE_BYTES + 2, 2**36)
                                                   for _ in range(3))]
HUGE_LAYOUT = [MAX_FILE_BYTES + 1, _rng.randint(2**30, 2**36)]


def _peak_rss_mib() -> float:
    """The process's peak memory so far (MiB), 0 where it cannot be read (Windows)."""
    try:
        import resource
    except ImportError:
        return 0.0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / 2**20 if sys.platform == "darwin" else peak / 2**10  # bytes there, KiB here


@pytest.mark.parametrize("size", HUGE_SVG)
def test_a_huge_drawing_is_refused_by_its_size_unread(tmp_path, size):
    sparse(tmp_path / "big.svg", size)
    before = _peak_rss_mib()
    line = refused(svg_scenario_file(tmp_path, "big.svg"), "runs.run.path", "big.svg",
                   "a drawing may hold at most 2 MiB")
    assert _peak_rss_mib() - before < 64, "the file was read"
    assert "holds" in line


def svg_scenario_file(tmp_path, name):
    path = tmp_path / "drawn.toml"
    path.write_text(scenario_text(f'{{ kind = "svg", file = "{name}", spacing = 0.02 }}'))
    return path


@pytest.mark.parametrize("size", HUGE_SCENARIO)
def test_a_huge_scenario_file_is_refused_by_its_size_unread(tmp_path, size):
    path = sparse(tmp_path / "big.toml", size)
    code, _, err, took, _ = check(path)
    assert code == 2 and err.count("\n") == 1 and took < HANG, err
    assert f"{path}: the file holds" in err and "at most 2 MiB" in err


@pytest.mark.parametrize("size", HUGE_LAYOUT)
def test_a_huge_layout_file_is_refused_by_its_size_unread(tmp_path, size):
    (tmp_path / "s.toml").write_text(scenario_text())
    scenario = load_scenario(tmp_path / "s.toml")
    layout = sparse(tmp_path / "layout.json", size)
    with pytest.raises(ScenarioError, match="the file holds .*a layout file may hold at most"):
        resolve_layout(scenario, str(layout), None)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_a_fifo_or_a_folder_as_a_drawing_is_refused_without_blocking(tmp_path):
    os.mkfifo(tmp_path / "pipe.svg")  # opened for reading, it would wait for a writer forever
    refused(svg_scenario_file(tmp_path, "pipe.svg"), "runs.run.path", "not a regular file")
    (tmp_path / "folder.svg").mkdir()
    refused(svg_scenario_file(tmp_path, "folder.svg"), "runs.run.path", "is a directory")


# --- 2. drawings whose reading would take minutes: bounded before the parser starts ----------

_rng = random.Random(SEED + 2)
ARITY = {"l": 2, "c": 6, "q": 4, "a": 7, "h": 1, "s": 4, "t": 2}


def _many_numbers(kind: str, extra: int) -> str:
    """A path of one command repeated (implicitly, as SVG allows) past MAX_SVG_NUMBERS."""
    arity = ARITY[kind]
    count = MAX_SVG_NUMBERS // arity + extra
    args = ["1 1 0 0 1 2 0"] if kind == "a" else [" ".join(str(_rng.randint(1, 9))
                                                          for _ in range(arity))]
    return HEAD + f'<path d="M 0 0 {kind} ' + " ".join(args * count) + '"/></svg>'


def _use_bomb(fan: int, levels: int) -> str:
    defs = '<path id="p0" d="M 0 0 L 1 1"/>' + "".join(
        f'<g id="p{i}">' + f'<use xlink:href="#p{i - 1}"/>' * fan + "</g>"
        for i in range(1, levels + 1))
    return HEAD + f'<defs>{defs}</defs><use xlink:href="#p{levels}"/>{GOOD_PATH}</svg>'


SLOW_SVG = [  # (what, svg, words the refusal holds)
    *((f"{kind} x {MAX_SVG_NUMBERS // ARITY[kind] + extra:,}", _many_numbers(kind, extra),
       f"more than {MAX_SVG_NUMBERS:,} numbers")
      for kind, extra in ((k, _rng.randint(1, 20_000))
                          for k in _rng.sample(sorted(ARITY), 6))),
    *((f"{n} closings in one piece", HEAD + '<path d="M 0 0' + " l 1 1 z" * n + '"/></svg>',
       f"more than {MAX_SVG_CLOSES:,} times")
      for n in (MAX_SVG_CLOSES + 1, _rng.randint(1000, 50_000))),
    *((f"<use> bomb {fan}^{levels}", _use_bomb(fan, levels),
       f"more than {MAX_SVG_ELEMENTS:,} groups")
      for fan, levels in ((2, 30), (_rng.randint(3, 6), 20))),
    ("<use> of itself", HEAD + f'<g id="a"><use xlink:href="#a"/></g>{GOOD_PATH}</svg>',
     "copies itself"),
    ("<use> of each other", HEAD + '<g id="a"><use href="#b"/></g><g id="b"><use href="#a"/>'
     f"</g>{GOOD_PATH}</svg>", "copies itself"),
    *((f"{n:,} nested groups", HEAD + "<g>" * n + GOOD_PATH + "</g>" * n + "</svg>",
       f"more than {MAX_SVG_DEPTH:,} deep")
      for n in (MAX_SVG_DEPTH + 1, _rng.randint(1000, 100_000))),
    (f"{MAX_SVG_ELEMENTS * 3:,} groups side by side", HEAD + "<g/>" * MAX_SVG_ELEMENTS * 3
     + GOOD_PATH + "</svg>", f"more than {MAX_SVG_ELEMENTS:,} groups"),
    ("a transform of 300,000 scale(", HEAD + '<path transform="' + "scale(" * 300_000
     + '" d="M 0 0 L 10 0"/></svg>', "characters long; at most 1,000"),
    ("a transform that is no transform", HEAD + '<path transform="' + "scale(" * 150
     + '" d="M 0 0 L 10 0"/></svg>', "not a list of matrix"),
    ("entities of entities", '<?xml version="1.0"?><!DOCTYPE svg [<!ENTITY a "aaaaaaaaaa">'
     + "".join(f'<!ENTITY {chr(98 + i)} "' + f"&{chr(97 + i)};" * 10 + '">' for i in range(9))
     + "]>" + HEAD + '<path id="&j;" d="M 0 0 L 100 0"/></svg>', "entities"),
    ("an entity used 3,000 times", '<?xml version="1.0"?><!DOCTYPE svg [<!ENTITY e "'
     + "x" * 1000 + '">]>' + HEAD + "".join(f'<g id="&e;{i}"/>' for i in range(3000))
     + GOOD_PATH + "</svg>", "entities expand it to more than 2 MiB"),
]


@pytest.mark.parametrize("what, svg, words", SLOW_SVG, ids=[c[0] for c in SLOW_SVG])
def test_a_drawing_that_would_take_minutes_is_refused_at_once(tmp_path, what, svg, words):
    line = refused(svg_scenario(tmp_path, svg), "runs.run.path", "drawn.svg", words)
    assert "100 m" not in line  # the old refusal blamed curves a drawing did not have


@pytest.mark.parametrize("metres", sorted(_rng.uniform(MAX_SVG_LENGTH * 1.01, 900)
                                          for _ in range(3)))
def test_a_path_too_long_to_follow_is_refused_with_its_true_length(tmp_path, metres):
    # a drawing in metres (1 unit is 1000 mm); three legs add up to the length
    legs = [metres * f for f in (0.5, 0.3, 0.2)]
    d = f"M 0 0 h {legs[0]} v {legs[1]} h {-legs[2]}"
    svg = ('<svg xmlns="http://www.w3.org/2000/svg" width="1000mm" height="1000mm" '
           f'viewBox="0 0 1 1"><path d="{d}"/></svg>')
    line = refused(svg_scenario(tmp_path, svg), "runs.run.path", "too long to follow")
    said = float(re.search(r"at least ([\d,.]+) m", line)[1].replace(",", ""))
    assert said == pytest.approx(metres, rel=1e-3)


def test_a_style_sheet_that_would_take_minutes_is_left_out(tmp_path):
    # a run of no '{' takes svgelements' style regex time quadratic in its length (7 s here)
    svg = HEAD + "<style>" + "a" * 30_000 + "</style>" + GOOD_PATH + "</svg>"
    code, out, err, took, caught = check(svg_scenario(tmp_path, svg))
    assert code == 0 and "Traceback" not in err and not caught and took < HANG, err


# --- 3. runs whose dominoes stand inside each other: refused before any layout is checked ----

_rng = random.Random(SEED + 3)
CROWDED = [
    *((f"line of {n} over {n * THICKNESS * f:.3g} m",
       f'{{ kind = "line", count = {n}, length = {(n - 1) * THICKNESS * f} }}')
      for n, f in ((1000, 0.002 / 0.007 / 999), *((_rng.randint(MAX_RUN_OVERLAPS + 2, 1000),
                                                   _rng.uniform(0.01, 0.9)) for _ in range(5)))),
    *((f"arc of {n} on a {r * 1000:.3g} mm radius",
       f'{{ kind = "arc", count = {n}, radius = {r}, start = 0, end = 720 }}')
      for n, r in ((_rng.randint(200, 1000), _rng.uniform(0.003, 0.01)) for _ in range(2))),
    ("polyline of 1000 over 2 mm", '{ kind = "polyline", points = [[0, 0], [0.002, 0]], '
     "count = 1000 }"),
    ("wave of 1000 over 2 mm", '{ kind = "wave", count = 1000, length = 0.002, width = 0 }'),
    ("branch of 3 x 333 over 2 mm", '{ kind = "branch", arm_count = 333, length = 0.002, '
     "width = 0.001 }"),
    ("x switch of 2 x 499 across 2 mm", '{ kind = "x_switch", count = 499, width = 0.002 }'),
]


@pytest.mark.parametrize("what, path", CROWDED, ids=[c[0] for c in CROWDED])
def test_a_run_of_dominoes_inside_each_other_is_refused_at_once(tmp_path, what, path):
    (tmp_path / "crowded.toml").write_text(scenario_text(path))
    refused(tmp_path / "crowded.toml", "runs.run.path", "of its dominoes overlap",
            f"more than {MAX_RUN_OVERLAPS} pairs")


def test_a_run_along_2_mm_of_drawing_is_refused_naming_the_spacing_it_needs(tmp_path):
    svg = HEAD + '<path d="M 0 0 L 2 0"/></svg>'  # 2 mm
    line = refused(svg_scenario(tmp_path, svg, "count = 1000"), "runs.run.path",
                   "less than a domino's thickness (7 mm)", "at least 7 mm apart")
    assert "0.002 mm apart" in line


def test_a_run_with_a_sharp_corner_still_loads_and_check_reports_the_overlap(tmp_path):
    # a few overlapping pairs are a layout's fault, which check names, not the file's
    (tmp_path / "corner.toml").write_text(scenario_text(
        '{ kind = "polyline", points = [[0, 0], [0.1, 0], [0.1, 0.05]], count = 16 }'))
    code, out, err, took, _ = check(tmp_path / "corner.toml")
    assert code == 1 and "INVALID" in out and "overlap" in out and took < HANG, out + err


# --- 4. coordinates near the largest float: refused quietly, no warning before the line ------

_rng = random.Random(SEED + 4)
HUGE = ["1e308", "-1e308", "1.7976931348623157e308", "1e309", "-1e999", "1e400", "5e307",
        "1e300", "-1e200", "1e12"]
TEMPLATES = [
    lambda v: f'<path d="M 0 0 L {v} 0"/>',
    lambda v: f'<path d="M 0 0 C {v} {v} -{v} {v} 10 10"/>'.replace("--", ""),
    lambda v: f'<path d="M 0 0 Q 10 {v} 20 0"/>',
    lambda v: f'<path transform="translate({v},0)" d="M 0 0 L 10 0"/>',
    lambda v: f'<path transform="scale({v.lstrip("-")})" d="M 0 0 L 10 10"/>',
    lambda v: f'<g transform="matrix({v.lstrip("-")} 0 0 1 0 0)"><path d="M 0 0 L 10 0"/></g>',
]
FAR = [("the reported curve", HEAD + '<path d="M 0 0 C 1e308 1e308 -1e308 1e308 10 10"/></svg>'),
       *((f"template {t} with {v}", HEAD + TEMPLATES[t](v) + "</svg>")
         for t, v in ((_rng.randrange(len(TEMPLATES)), _rng.choice(HUGE)) for _ in range(11))),
       ("a size of 1e308 mm", HEAD.replace('"300mm" height="200mm"',
                                           '"1e308mm" height="1e308mm"') + GOOD_PATH + "</svg>")]


@pytest.mark.parametrize("what, svg", FAR, ids=[c[0] for c in FAR])
def test_coordinates_near_the_largest_float_are_refused_in_one_quiet_line(tmp_path, what, svg):
    line = refused(svg_scenario(tmp_path, svg), "runs.run.path", "drawn.svg")
    assert re.search("not a finite number|m from the drawing's origin|too long|drawing's width",
                     line), line
    assert "Warning" not in line


# --- 5. control characters in what a file says: escaped wherever it is printed ---------------

_rng = random.Random(SEED + 5)


def _toml_escaped(text: str) -> str:
    return "".join(f"\\u{ord(c):04x}" if c in CONTROLS or c in '"\\' else c for c in text)


DESCRIPTIONS = [
    "".join(CONTROLS),  # every C0 and C1 control and DEL
    "\x1b]0;pwned\x07\x1b[2Jcleared\x1b[31mred",  # the reported title, clear and colour
    *("".join(_rng.choice([*CONTROLS, "a", "b", " ", "é"]) for _ in range(_rng.randint(1, 40)))
      for _ in range(10)),
]


@pytest.mark.parametrize("description", DESCRIPTIONS, ids=[f"d{i}" for i in range(12)])
def test_control_characters_of_a_description_are_printed_escaped(tmp_path, description):
    (tmp_path / "desc.toml").write_text(scenario_text(description=_toml_escaped(description)))
    code, out, err, took, _ = check(tmp_path / "desc.toml")
    assert code == 0 and took < HANG, err
    first = out.splitlines()[0]
    assert first == f"hostile: {printable(description)}"
    assert not RAW_CONTROL.search(out)
    for c in set(description) & set(CONTROLS):
        assert repr(c)[1:-1] in first


NAMED = [("objects", 'objects."{}" = {{ part = "ball" }}'),
         ("runs", 'runs."{}" = {{ domino = ' + DOMINO.replace("{", "{{").replace("}", "}}")
          + ', path = {{ kind = "line", count = 2, length = 0.02 }} }}'),
         ("events", 'events."{}" = {{ type = "toppling", body = "run[0]", angle = 45 }}'),
         ("layouts", 'layouts."{}" = {{}}'),
         ("objects.ball.part", 'objects.ball = {{ part = "{}" }}')]
BAD_NAMES = [(where, line, "".join(_rng.choice(["x", c, "\x1b[2J"]) for _ in range(4)) + c)
             for where, line, c in ((*_rng.choice(NAMED), _rng.choice(CONTROLS))
                                    for _ in range(10))]


@pytest.mark.parametrize("where, template, name", BAD_NAMES,
                         ids=[f"{w}-{i}" for i, (w, _, _) in enumerate(BAD_NAMES)])
def test_control_characters_in_names_are_escaped_in_the_one_line(tmp_path, where, template,
                                                                  name):
    text = scenario_text(top=template.format(_toml_escaped(name)) + "\n")
    (tmp_path / "names.toml").write_text(text)
    line = refused(tmp_path / "names.toml", where if "." in where else where + ".")
    assert repr(name)[1:-1][:30] in line  # quoted as Python does, its controls escaped


@pytest.mark.parametrize("bad", ["\x1b]0;pwned\x07", "\x9b2J\x85", "\x7f\u202e"])
def test_a_file_named_with_control_characters_is_named_escaped(tmp_path, bad):
    path = tmp_path / f"bad{bad}.toml"
    path.write_text("name = [\n")  # not TOML
    refused(path, "", "not valid TOML")
    path.write_text(scenario_text('{ kind = "svg", file = "' + _toml_escaped(f"m{bad}.svg")
                                  + '", spacing = 0.02 }'))
    line = refused(path, "runs.run.path.file", "expected a string")
    assert repr(f"m{bad}.svg")[1:-1] in line
