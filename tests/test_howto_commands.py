"""Every command of the how-to guides (``docs/how-to/*.md``) and of the README, run as a reader
runs them: each ``sh``/``bash`` block's lines, page after page, in one folder that holds what a
checkout holds (``scenarios/``, ``parts/``, ``tests/data/``, ``tools/``), with ``uv run NAME``
the environment's ``NAME``. Each must exit as the page says (0 unless :data:`EXITS` says
why not), and the files it names with ``--out``, ``--html``, ``--video`` or ``--run`` (and the
run directory its comment names) must be there and not empty. ``rgmcad live`` runs until it
prints its address and its page shows the first run, then gets Ctrl-C and must stop
cleanly (status 0, no traceback), leaving no process behind.

What a reader makes by hand is made the way a reader makes it, just before the command that
reads it: a layout saved by the live page's Save button, a scan and a phone photo of a sheet of
the template the print page printed. Commands too long for CI, or that need machines we do not
have, are in :data:`NOT_RUN` with the reason; they are still parsed by the real command line
and their scenario and named layouts loaded, and every entry must still match a command of
the docs. Slow (about 5 minutes on 2 quiet cores): CI runs it after the suite (``.ci/run``).
Both slow runs serve on live.md's and the README's port, 8767: the suite's ``--dist loadfile``
keeps them in one worker, one after the other."""

from __future__ import annotations

import os
import re
import shlex
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from tests._support import popen_as_terminal

ROOT = Path(__file__).resolve().parent.parent
HOWTO = ROOT / "docs" / "how-to"
BIN = Path(sys.executable).parent
SHELL = re.compile(r"^[ \t]*```(?:sh|bash)\n(.*?)^[ \t]*```", re.M | re.S)  # in a list too
COPIED = ("scenarios", "parts", "tests/data", "tools")
"""What the folder the commands run in holds of a checkout."""

PAGES = ("simulate", "watch", "optimize", "evaluate", "live", "print", "supports",
         "part-family", "benchmark", "cluster")
"""The how-to pages with commands, in an order where a command's inputs are made first
(optimize.md makes runs/simple-s0/, which evaluate.md and live.md read)."""

NOT_RUN = {
    "optimize scenarios/ballrun.toml --seed 1 --run runs/br1":
        "ballrun at the default budget: 7 minutes on the shared 2 cores",
    "supports ballrun --layout runs/ballrun-s0/layout.json":
        "needs ballrun's default-budget run (optimize ballrun: minutes); supports runs on simple",
    "optimize tools/generality/domino_arc.toml --start hand":
        "a 16-dimensional scenario at the default budget: tens of minutes",
    "optimize scenarios/simple.toml --set second_look_rounds=3":
        "a second default-budget run of simple (a minute); --set is run by tests/test_set_option.py",
    "benchmark simple --methods ours,b1,cma --trials 2":
        "two default-budget runs of ours (46 s of CPU each on simple), the baselines, each "
        "layout's rho_g: minutes",
    "benchmark ballrun --trials 3":
        "three default-budget ballrun runs and the baselines: an hour on 2 cores",
    "optimize ballrun --scheduler local:4":
        "ballrun at the default budget on 4 workers: minutes; local:N is run below with local:2",
    "dask scheduler": "a scheduler for other machines; tests/test_dask.py starts one",
    "dask worker tcp://HOST:8786": "a worker of a scheduler on another machine (HOST)",
    "--scheduler tcp://HOST:8786": "a scheduler on another machine (HOST)",
    "tools/live_latency.py --saves 10":
        "headless Chromium over 6 scenarios x 10 saves, then 2 x 100 saves: minutes",
    "uv run pytest": "the test suite itself (or one file of it)",
    "uv run ruff check .": "lint: tests/test_lint.py runs ruff",
    "uv run lint-imports": "tests/test_structure.py runs it",
    "uv run mkdocs build": "tests/test_docs.py builds the site in strict mode",
    "uv run mkdocs serve": "a server for editing the docs; what it serves is built by tests/test_docs.py",
}
"""Command substring: why it is not run (only parsed)."""

EXITS = {
    "check scenarios/ballrun.toml": (1, "ballrun's initial layout is invalid: check says so, status 1"),
    "--vector 0.9,0.3,0.6,0.5": (1, "that layout fails (simulate: status 1 on failure)"),
    "--until 0.5": (1, "a run stopped early fails its events still awake"),
    "--draw 3": (1, "watch.md: that hand's build fails (solved survives 1 of draws 0-3)"),
}
"""Command substring: (the exit status the page documents, why)."""

OUTPUT_FLAGS = ("--out", "--html", "--video", "--run")
RUN_DIR_NOTE = re.compile(r"#.*?\b(runs/[\w.=+-]+)/")


def commands(text: str) -> list[str]:
    """The command lines of the ``sh``/``bash`` blocks of a page: a ``\\`` continuation joined,
    output shown as a ``#`` line left out."""
    out = []
    for block in SHELL.findall(text):
        for line in block.replace("\\\n", " ").splitlines():
            if line.strip() and not line.lstrip().startswith("#"):
                out.append(line.strip())
    return out


def page_commands() -> list[tuple[str, str]]:
    """(page, command) of every how-to page, pages in :data:`PAGES` order."""
    return [(page, c) for page in PAGES for c in commands((HOWTO / f"{page}.md").read_text())]


def readme_commands() -> tuple[str, list[str]]:
    """(the scenario the README asks to save as first.toml, its command lines)."""
    text = (ROOT / "README.md").read_text()
    scenario = re.search(r"^```toml\n(.*?)^```", text, re.M | re.S).group(1)
    assert "save it as `first.toml`" in text
    return scenario, commands(text)


def not_run(command: str) -> str | None:
    return next((why for part, why in NOT_RUN.items() if part in command), None)


def shell(command: str) -> str:
    """``command`` as bash runs it here: ``uv run NAME`` is this environment's NAME."""
    return re.sub(r"\buv run (\S+)", lambda m: shlex.quote(
        sys.executable if m[1] == "python" else str(BIN / m[1])), command)


def calls(command: str) -> list[list[str]]:
    """The argv of each program a command line calls (``a && b | c``), ``uv run`` dropped."""
    lexer = shlex.shlex(command, posix=True, punctuation_chars=";&|")
    lexer.whitespace_split, lexer.commenters = True, "#"
    argv, out = [], []
    for token in [*lexer, ";"]:
        if token in (";", "&&", "|", "||", "&"):
            if argv:
                out.append(argv[2:] if argv[:2] == ["uv", "run"] else argv)
            argv = []
        else:
            argv.append(token)
    return out


def outputs(command: str) -> list[str]:
    """The files and folders a command says it writes: the value of each output flag, and a
    run directory its comment names (``# runs/simple-s0/``)."""
    found = []
    for argv in calls(command):
        found += [argv[i + 1] for i, a in enumerate(argv[:-1]) if a in OUTPUT_FLAGS]
    return found + RUN_DIR_NOTE.findall(command)


def parse_and_load(argv: list[str], folder: Path) -> None:
    """``rgmcad ARGV`` parsed by the command line's parser, its scenario loaded, and each layout
    it names found: a named layout of the scenario, its run's (``runs/SCENARIO-s0``) or a file
    in ``folder``."""
    from rgmcad.cli import build_parser
    from rgmcad.runs.workflow import default_run_dir
    from rgmcad.scene.loader import load_scenario
    from rgmcad.shipped import scenario_path

    args = build_parser().parse_args(argv)
    if not hasattr(args, "scenario"):
        return
    path = Path(args.scenario) if (folder / args.scenario).is_file() else None
    scenario = load_scenario(folder / path if path else scenario_path(args.scenario),
                             parts_dir=args.parts)
    runs = {str(default_run_dir(scenario.name, budget, 0) / "layout.json")
            for budget in ("default", "small")}  # what `rgmcad optimize SCENARIO` writes
    for key in ("layout", "compare", "start", "reference"):
        value = getattr(args, key, None)
        for name in value if isinstance(value, list) else [value] if value else []:
            assert name in scenario.layouts or name in runs or (folder / name).is_file(), (
                f"rgmcad {shlex.join(argv)}: --{key} {name} is neither a layout of "
                f"{scenario.name} ({', '.join(scenario.layouts)}), nor the layout of its "
                f"run ({', '.join(sorted(runs))}), nor a file")


# --- the cheap checks: what is read, and the exceptions ------------------------------------------


def test_every_howto_page_with_commands_is_run_in_an_order():
    with_commands = {p.stem for p in HOWTO.glob("*.md") if commands(p.read_text())}
    assert with_commands == set(PAGES)
    lines = [c for _, c in page_commands()]
    assert len(lines) > 40
    assert any(c.startswith("for x in") for c in lines)  # a loop stays one line
    assert any("--physics friction=0,mass=0" in c and "--draw 3" in c for c in lines)  # "\"
    assert not any(c.startswith("#") for c in lines)  # shown output is no command


def test_every_exception_still_matches_a_command_of_the_docs():
    every = [c for _, c in page_commands()] + readme_commands()[1]
    for table in (NOT_RUN, EXITS, BY_HAND):
        stale = [part for part in table if not any(part in c for c in every)]
        assert not stale, f"no command of the docs holds {stale}: remove them from the test"
    stale = [pattern for pattern in SHOWN if not any(re.search(pattern, c) for c in every)]
    assert not stale, f"no command of the docs matches {stale}: remove them from the test"


@pytest.mark.slow  # a few seconds: the parser's and the scenarios' imports
def test_the_commands_not_run_parse_and_name_what_exists(monkeypatch):
    # the parser asks a tcp:// scheduler whether it answers: here only its form is checked
    import rgmcad.runs.dask_executor

    monkeypatch.setattr(rgmcad.runs.dask_executor, "ask_scheduler", lambda address: None)
    every = [c for _, c in page_commands()] + readme_commands()[1]
    for command in filter(not_run, every):
        for argv in calls(command):
            if argv[0] == "rgmcad":
                parse_and_load(argv[1:], ROOT)
            elif argv[0] == "python":  # a tool: its own parser knows each option given
                helped = subprocess.run([sys.executable, str(ROOT / argv[1]), "--help"],
                                        capture_output=True, text=True, cwd=ROOT, timeout=120)
                assert helped.returncode == 0, f"{command}\n{helped.stderr[-2000:]}"
                assert not [a for a in argv if a.startswith("--") and a not in helped.stdout]
            else:
                assert (BIN / argv[0]).is_file(), f"{command}: {argv[0]} is not installed"


def test_commands_are_read_as_a_shell_reads_them():
    line = "cp -r parts my_parts && uv run rgmcad --parts my_parts check simple   # comment"
    assert calls(line) == [["cp", "-r", "parts", "my_parts"],
                           ["rgmcad", "--parts", "my_parts", "check", "simple"]]
    assert outputs("uv run rgmcad optimize simple --budget small  # runs/simple-small-s0/") == \
        ["runs/simple-small-s0"]
    assert outputs("uv run rgmcad template x --out t --json") == ["t"]
    assert shell("uv run python tools/x.py") == f"{shlex.quote(sys.executable)} tools/x.py"
    assert shell("uv run rgmcad -q simulate") == f"{shlex.quote(str(BIN / 'rgmcad'))} -q simulate"


# --- what a reader makes by hand --------------------------------------------------------------


def save_layout_as_the_live_page_does(folder: Path) -> None:
    """scenarios/simple.layouts.json as the live page's Save layout writes it: the sliders at
    simple's ``solved``, saved as ``mine``."""
    from rgmcad.live.files import write_saved
    from rgmcad.scene.design_space import vector_from_values
    from rgmcad.scene.layout_files import layout_document, resolve_layout
    from rgmcad.scene.loader import load_scenario

    scenario = load_scenario(folder / "scenarios" / "simple.toml")
    _, values = resolve_layout(scenario, "solved", None)
    document = layout_document(scenario, vector_from_values(scenario, values), name="mine",
                               made_from="solved")
    write_saved(folder / "scenarios" / "simple.layouts.json", "mine", document)


def _printed_sheet(folder: Path):
    """The last page of the ballrun template print.md made (a tiled sheet), grey, 300 dpi."""
    import numpy as np
    import pypdfium2 as pdfium

    doc = pdfium.PdfDocument(str(folder / "ballrun-template" / "template.pdf"))
    try:
        return np.asarray(doc[len(doc) - 1].render(scale=300 / 72).to_pil().convert("L"))
    finally:
        doc.close()


def _photo_suite():
    import importlib.util

    spec = importlib.util.spec_from_file_location("photo_suite", ROOT / "tools" / "photo_suite.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["photo_suite"] = module  # its dataclass looks its module up there
    spec.loader.exec_module(module)
    return module


def scan_a_sheet_printed_small(folder: Path) -> None:
    """scan.png: that sheet printed at 97 % ("fit to page") and scanned at 300 dpi."""
    import cv2
    import numpy as np
    from PIL import Image

    page = _printed_sheet(folder)
    h, w = page.shape
    s = 0.97
    shrink = [[s, 0, (1 - s) * w / 2], [0, s, (1 - s) * h / 2]]
    printed = cv2.warpAffine(page, np.float32(shrink), (w, h), flags=cv2.INTER_AREA,
                             borderValue=255)
    Image.fromarray(printed).save(folder / "scan.png", dpi=(300, 300))


def photograph_a_sheet(folder: Path) -> None:
    """photo.jpg: that sheet lying on a table, taken from 20 degrees off vertical (3 MP)."""
    suite = _photo_suite()
    suite.photograph(_printed_sheet(folder), suite.Shot(tilt_deg=20, mp=3, margin_mm=30, seed=1),
                     folder / "photo.jpg")


BY_HAND = {
    "--layout scenarios/simple.layouts.json": save_layout_as_the_live_page_does,
    "verify-print scan.png": scan_a_sheet_printed_small,
    "verify-print photo.jpg": photograph_a_sheet,
}
"""Command substring: what the reader made before it."""

SHOWN = {
    r"live scenarios/simple\.toml$": "simple: live page at http://127.0.0.1:8767/ (Ctrl-C stops)",
    r"verify-print scan\.png": "scale 97.0 %: reprint at actual size (100 %, no 'fit to page')",
    r"verify-print photo\.jpg": '"verdict": "ok"',
}
"""Command (a regular expression): what it prints, as its page shows it (live.md, print.md),
or of what the reader made (the photo)."""


# --- running ----------------------------------------------------------------------------------


def _environment() -> dict:
    # no browser opens (webbrowser honours $BROWSER; without a display none is tried anyway)
    return {**os.environ, "COLUMNS": "200", "BROWSER": "true"}


def check_shown(command: str, printed: str) -> None:
    said = [text for pattern, text in SHOWN.items() if re.search(pattern, command)]
    said += re.findall(r"#\s*(outcome: [^.]*)", command)  # README: "# outcome: success (2/2 ..."
    assert all(s in printed for s in said), f"{command}: it printed\n{printed[-2000:]}"


def run_command(command: str, folder: Path) -> str:
    """Run one command line in ``folder``; checks its exit status and outputs; its output."""
    done = subprocess.run(["bash", "-c", shell(command)], cwd=folder, env=_environment(),
                          capture_output=True, text=True, timeout=900)
    status, why = next((v for part, v in EXITS.items() if part in command), (0, "success"))
    printed = done.stdout + done.stderr
    assert done.returncode == status, (
        f"{command}\nexit {done.returncode}, not {status} ({why})\n{printed[-3000:]}")
    check_shown(command, printed)
    for out in outputs(command):
        path = folder / out
        assert path.exists(), f"{command}: wrote no {out}\n{printed[-2000:]}"
        assert path.stat().st_size > 0 if path.is_file() else any(path.iterdir()), out
    return printed


def _still_running(pgid: int, started: list) -> list[int]:
    """The processes of process group ``pgid``, and those of ``started``, still running."""
    import psutil

    alive = set()
    for p in psutil.process_iter(["status"]):
        try:
            if os.getpgid(p.pid) == pgid and p.info["status"] != psutil.STATUS_ZOMBIE:
                alive.add(p.pid)
        except (ProcessLookupError, psutil.Error):
            continue
    for p in started:
        try:
            if p.is_running() and p.status() != psutil.STATUS_ZOMBIE:
                alive.add(p.pid)
        except psutil.Error:
            continue
    return sorted(alive)


def _first_picture(url: str, proc: subprocess.Popen, timeout: float = 120) -> None:
    """Wait until the page at ``url`` has its first run to show, as the reader sees it."""
    import json
    import urllib.request

    deadline = time.monotonic() + timeout
    while True:
        with urllib.request.urlopen(url + "state", timeout=30) as answer:
            state = json.loads(answer.read())
        if state.get("view", 0) >= 1 and not state.get("busy"):
            return
        assert proc.poll() is None and time.monotonic() < deadline, state
        time.sleep(0.1)


def serve_then_stop(command: str, folder: Path) -> str:
    """Run ``rgmcad live ...`` until it prints its address and its page shows the first run,
    then Ctrl-C: it must stop with status 0 and no traceback, and nothing it started may keep
    running."""
    import psutil

    proc = popen_as_terminal(["bash", "-c", "exec " + shell(command)], cwd=folder,
                             env=_environment(), stdout=subprocess.PIPE,
                             stderr=subprocess.STDOUT, text=True)
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(iter(proc.stdout.readline, "")),
                              daemon=True)
    reader.start()
    try:
        deadline = time.monotonic() + 180
        while not (url := re.search(r"live page at (http://\S+/)", "".join(lines))):
            assert proc.poll() is None, f"{command}: exit {proc.returncode}\n{''.join(lines)}"
            assert time.monotonic() < deadline, f"{command}: no address\n{''.join(lines)}"
            time.sleep(0.1)
        _first_picture(url[1], proc)
        started = psutil.Process(proc.pid).children(recursive=True)  # its simulation worker
        os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C in the terminal: the whole group
        status = proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    reader.join(timeout=10)
    printed = "".join(lines)
    assert status == 0 and "Traceback" not in printed, f"{command}: Ctrl-C: exit {status}\n{printed}"
    check_shown(command, printed)
    deadline = time.monotonic() + 20
    while left := _still_running(proc.pid, started):
        assert time.monotonic() < deadline, f"{command}: processes left after Ctrl-C: {left}"
        time.sleep(0.2)
    return printed


def reader_folder(tmp_path: Path) -> Path:
    import shutil

    for part in COPIED:
        shutil.copytree(ROOT / part, tmp_path / part,
                        ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    return tmp_path


def _cpu_of_children() -> float:
    import resource

    used = resource.getrusage(resource.RUSAGE_CHILDREN)
    return used.ru_utime + used.ru_stime


def run_all(lines: list[tuple[str, str]], folder: Path) -> list[tuple[float, str]]:
    """Run each (page, command) not in :data:`NOT_RUN`, a command already run in ``folder``
    once only (evaluate.md repeats one of optimize.md); (seconds, command) of each, printed
    with the CPU seconds it took (the load of a shared machine aside)."""
    times, done = [], set()
    for page, command in lines:
        if not_run(command) or command in done:
            continue
        done.add(command)
        for part, make in BY_HAND.items():
            if part in command:
                make(folder)
        start, cpu = time.perf_counter(), _cpu_of_children()
        if re.search(r"\brgmcad live\b", command):
            serve_then_stop(command, folder)
        else:
            run_command(command, folder)
        times.append((time.perf_counter() - start, f"{page}: {command}"))
        print(f"{times[-1][0]:6.1f} s ({_cpu_of_children() - cpu:5.1f} s CPU)  {times[-1][1]}",
              flush=True)
    return times


@pytest.mark.slow
def test_every_howto_command_runs_as_written(tmp_path, capsys):
    with capsys.disabled():  # each command's time, as it ends
        print()
        times = run_all(page_commands(), reader_folder(tmp_path))
        print(f"how-to commands: {len(times)} run in {sum(t for t, _ in times):.0f} s")
    assert len(times) >= 30


@pytest.mark.slow
def test_every_readme_command_runs_as_written(tmp_path, capsys):
    scenario, lines = readme_commands()
    folder = reader_folder(tmp_path)
    (folder / "first.toml").write_text(scenario)
    with capsys.disabled():
        print()
        times = run_all([("README", c) for c in lines], folder)
        print(f"README commands: {len(times)} run in {sum(t for t, _ in times):.0f} s")
    assert any("first.toml" in c for _, c in times)
