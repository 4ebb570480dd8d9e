"""What goes wrong with a run as users meet it: ``kill -9`` of ``rgmcad optimize`` (a real
process, resumed by the same command), a run directory damaged on disk (garbage lines,
malformed records, a broken result or model, a deleted settings file), another process on the
directory, and flags or places that cannot work, refused before any simulation."""

from __future__ import annotations

import contextlib
import json
import logging
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from rgmcad.errors import RunDirectoryError, UsageError
from rgmcad.runs.evaluation import evaluate_layout
from rgmcad.runs.executor import PoolExecutor, parent_only
from rgmcad.runs.store import REJECTED, RESULT, SETTINGS, SIMULATIONS, RunStore, run_identity
from rgmcad.runs.workflow import optimize_scenario
from tests._support import TINY, cli_output, popen_as_terminal

ROOT = Path(__file__).resolve().parent.parent
SIMPLE = "scenarios/simple.toml"


def _optimize(run, **changes):
    return optimize_scenario(SIMPLE, **{"seed": 3, "budget": "small", "settings": TINY,
                                        "run_dir": run, "workers": 1, **changes})



# --- kill -9 ---------------------------------------------------------------------------------


def _optimize_command(run: Path, extra: tuple[str, ...] = ()) -> list[str]:
    return [sys.executable, "-m", "rgmcad.cli", "optimize", SIMPLE, "--budget", "small",
            "--workers", "2", "--run", str(run), "--json", *extra]


def _stat(pid: int) -> list[str] | None:
    """Fields of /proc/PID/stat after the command name (state first), None when gone."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None


def _children(pid: int) -> dict[int, str]:
    """{pid: start time} of the processes whose parent is ``pid``."""
    out = {}
    for entry in Path("/proc").iterdir():
        fields = _stat(int(entry.name)) if entry.name.isdigit() else None
        if fields is not None and fields[1] == str(pid):
            out[int(entry.name)] = fields[19]
    return out


def _running(pid: int, start: str) -> bool:
    fields = _stat(pid)
    return fields is not None and fields[19] == start and fields[0] not in ("Z", "X")


START = ("--start", "solved")
CENTRED = ("--centering", "always")


def _uninterrupted(tmp_path_factory, extra=()):
    """The library call ``rgmcad optimize simple --budget small --workers 2 EXTRA`` makes, in
    this process: its run directory and its summary (what ``--json`` prints). The commands
    the tests kill are real processes; their uninterrupted reference needs no process of its
    own (nor the CAD export and report the command writes after the result)."""
    run = tmp_path_factory.mktemp("uninterrupted") / "run"
    options = {START: {"starts": ["solved"]}, CENTRED: {"centering": "always"}, (): {}}[extra]
    done = optimize_scenario(SIMPLE, budget="small", run_dir=run, workers=2, **options)
    return run, json.loads(json.dumps(done.summary))


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    """``rgmcad optimize simple --budget small --workers 2``, uninterrupted: (run dir, the
    JSON it prints)."""
    return _uninterrupted(tmp_path_factory)


@pytest.fixture(scope="module")
def small_start_run(tmp_path_factory):
    """The same with ``--start solved``."""
    return _uninterrupted(tmp_path_factory, START)


@pytest.fixture(scope="module")
def small_centred_run(tmp_path_factory):
    """The same with ``--centering always``."""
    return _uninterrupted(tmp_path_factory, CENTRED)


def _kill_point(reference: dict, extra: tuple[str, ...]) -> int:
    """Journal lines at which to kill: early in the run, or 16 simulations into the
    centring (its simulations come last but for the check's)."""
    if extra != CENTRED:
        return 10
    by_stage = reference["simulations_by_stage"]  # what comes after: the check's, the look's
    return (reference["simulations"] - by_stage["centering"] - by_stage.get("second look", 0)
            - by_stage.get("tolerance check", 0) + 16)


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads processes in /proc")
# with a start and during centring: CI's second pass (.ci/run), so the default suite stays
# under 5 minutes
@pytest.mark.parametrize("uninterrupted, extra", [
    pytest.param("small_run", (), id="plain"),
    pytest.param("small_start_run", START, id="with-start", marks=pytest.mark.slow),
    pytest.param("small_centred_run", CENTRED, id="during-centring", marks=pytest.mark.slow)])
def test_kill_9_of_optimize_then_the_same_command_resumes_to_the_same_result(
        uninterrupted, extra, request, tmp_path):
    _, reference = request.getfixturevalue(uninterrupted)
    run = tmp_path / "run"
    killed = subprocess.Popen(_optimize_command(run, extra), cwd=ROOT,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    workers: dict[int, str] = {}
    try:
        journal = run / SIMULATIONS
        deadline, kill_at = time.monotonic() + 120, _kill_point(reference, extra)
        while not (journal.exists() and journal.read_bytes().count(b"\n") >= kill_at):
            assert killed.poll() is None and time.monotonic() < deadline, "not killed in time"
            time.sleep(0.01)
        workers = _children(killed.pid)
        assert len(workers) == 2  # the pool's workers, busy simulating
        os.kill(killed.pid, signal.SIGKILL)  # the main process only, as `kill -9 PID` does
        killed.wait()
        done_before = journal.read_bytes().count(b"\n")
        resumed = subprocess.run(_optimize_command(run, extra), cwd=ROOT,
                                 capture_output=True, text=True, timeout=300)
        assert resumed.returncode == 0, resumed.stderr[-2000:]
        summary = json.loads(resumed.stdout)
        assert summary["vector"] == reference["vector"]
        assert summary["probability"] == reference["probability"]
        assert summary["simulations"] == reference["simulations"]
        assert summary["replayed"] >= done_before > 0
        assert done_before < reference["simulations"]  # killed before its last simulation
        assert summary["centering"] == reference["centering"]
        deadline = time.monotonic() + 5
        while any(_running(p, s) for p, s in workers.items()) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not [p for p, s in workers.items() if _running(p, s)], "workers outlived it"
    finally:
        for pid, start in workers.items():  # whatever happened, leave nothing running
            if _running(pid, start):
                os.kill(pid, signal.SIGKILL)
        if killed.poll() is None:
            killed.kill()
            killed.wait()


# the run of `_optimize_command`, killed with SIGKILL by itself at its ``at``-th simulation of
# the second look (the moment cannot be hit from outside: the look is a second on simple)
_KILLED_IN_THE_SECOND_LOOK = """
import os, signal, sys
from rgmcad.runs.workflow import RunProgress, optimize_scenario

class KillInTheLook(RunProgress):
    look = None

    def stage(self, name, total=None):
        if name == "second look":
            self.look = 0

    def simulated(self, record, replayed=False):
        if self.look is not None:
            self.look += 1
            if self.look == int(sys.argv[2]):
                os.kill(os.getpid(), signal.SIGKILL)

optimize_scenario(sys.argv[1], budget="small", run_dir=sys.argv[3], workers=2,
                  progress=KillInTheLook())
"""


@pytest.mark.slow  # CI's second pass (.ci/run): the default suite stays under 5 minutes
def test_kill_9_during_the_second_look_then_the_same_command_resumes_to_the_same_result(
        small_run, tmp_path):
    _, reference = small_run
    assert reference["simulations_by_stage"]["second look"] >= 3  # the kill lands inside it
    run = tmp_path / "run"
    killed = subprocess.run([sys.executable, "-c", _KILLED_IN_THE_SECOND_LOOK, SIMPLE, "2",
                             str(run)], cwd=ROOT, capture_output=True, timeout=300)
    assert killed.returncode == -signal.SIGKILL, killed.stderr[-2000:]
    by_stage = reference["simulations_by_stage"]  # the tolerance check comes after the look
    before_look = (reference["simulations"] - by_stage["second look"]
                   - by_stage.get("tolerance check", 0))
    done_before = (run / SIMULATIONS).read_bytes().count(b"\n")
    assert before_look + 2 <= done_before < reference["simulations"]
    resumed = subprocess.run(_optimize_command(run), cwd=ROOT, capture_output=True, text=True,
                             timeout=300)
    assert resumed.returncode == 0, resumed.stderr[-2000:]
    summary = json.loads(resumed.stdout)
    for key in ("vector", "probability", "simulations", "simulations_by_stage", "second_look",
                "source"):
        assert summary[key] == reference[key], key
    assert summary["replayed"] >= done_before


def _ctrl_c_at(command: list[str], journal: Path, lines: int) -> tuple[float, str, dict]:
    """Run ``command`` in its own session (as a terminal's foreground job), press Ctrl-C
    (SIGINT to the whole process group) once the journal holds ``lines`` lines: (seconds to
    exit, stderr, {pid: start} of its workers then)."""
    job = popen_as_terminal(command, cwd=ROOT, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    workers: dict[int, str] = {}
    try:
        deadline = time.monotonic() + 120
        while not (journal.exists() and journal.read_bytes().count(b"\n") >= lines):
            assert job.poll() is None and time.monotonic() < deadline, "not interrupted in time"
            time.sleep(0.01)
        workers = _children(job.pid)
        pressed = time.monotonic()
        os.killpg(job.pid, signal.SIGINT)
        try:  # a hang (a worker holding the pool's lock) fails here, on any machine
            _, err = job.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            pytest.fail("rgmcad still running 60 s after Ctrl-C")
        return time.monotonic() - pressed, err, workers
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(job.pid, signal.SIGKILL)  # whatever happened, leave nothing running
        job.wait()


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads processes in /proc")
@pytest.mark.slow  # CI's second pass (.ci/run): the default suite stays under 5 minutes
def test_ctrl_c_ends_optimize_at_once_in_one_line_and_the_same_command_resumes(small_run,
                                                                               tmp_path):
    # causality_switch's simulations take about a second, so a worker is mid-simulation
    # when the key is pressed (workers that took the signal themselves once left the pool's
    # lock held and the command hung, or died and printed a broken pool's traceback; a
    # command that waited for its running simulations took 7-20 s to stop)
    run = tmp_path / "switch"
    switch = [sys.executable, "-m", "rgmcad.cli", "optimize", "causality_switch", "--budget",
              "small", "--workers", "2", "--run", str(run), "-q"]
    for _ in range(2):  # two presses, the same command started again after the first
        journal = run / SIMULATIONS  # lines come in batches: 6 more than the run has now
        lines = (journal.read_bytes().count(b"\n") if journal.exists() else 0) + 6
        seconds, err, workers = _ctrl_c_at(switch, journal, lines)
        print(f"stopped {seconds:.2f} s after Ctrl-C")  # no bound here but the hang's, below
        assert err == "rgmcad: interrupted\n", (seconds, err[-2000:])
        assert len(workers) == 2 and not [p for p, s in workers.items() if _running(p, s)]
    # and an interrupted run continues to the result it would have had
    _, reference = small_run
    run = tmp_path / "simple"
    seconds, err, _ = _ctrl_c_at(_optimize_command(run, ("-q",)), run / SIMULATIONS, 10)
    assert err == "rgmcad: interrupted\n", (seconds, err[-2000:])
    resumed = subprocess.run(_optimize_command(run), cwd=ROOT, capture_output=True, text=True,
                             timeout=300)
    assert resumed.returncode == 0, resumed.stderr[-2000:]
    summary = json.loads(resumed.stdout)
    assert (summary["vector"], summary["simulations"]) == (reference["vector"],
                                                           reference["simulations"])
    assert summary["replayed"] >= 10


@pytest.mark.skipif(not Path("/proc/self/fd").exists(), reason="reads /proc/self/fd")
def test_pool_workers_keep_no_file_of_their_parent(tmp_path):
    with open(tmp_path / "journal", "ab") as f:
        parent_only(f.fileno())
        try:
            with PoolExecutor(2) as pool:
                seen = list(pool.map(os.readlink, [f"/proc/self/fd/{f.fileno()}"] * 2))
        finally:
            parent_only(f.fileno(), keep=False)
    assert seen == [os.devnull, os.devnull]


def test_a_lock_held_by_a_live_process_names_it_and_a_dead_owner_s_lock_is_free(tmp_path):
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys; from pathlib import Path; "
         "from rgmcad.runs.lock import DirectoryLock; lock = DirectoryLock(Path(sys.argv[1])); "
         "print('locked', flush=True); sys.stdin.read()", str(tmp_path)],
        cwd=ROOT, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        with pytest.raises(RunDirectoryError, match=f"another rgmcad process \\(pid "
                           f"{holder.pid}, running since .*\\) is using this run directory"):
            RunStore(tmp_path, run_identity("s", "0" * 64, 0, TINY))
    finally:
        holder.kill()
        holder.wait()
    # its record is still in the lock file, but the kernel released the lock with it
    assert json.loads((tmp_path / ".lock").read_text())["pid"] == holder.pid
    with RunStore(tmp_path, run_identity("s", "0" * 64, 0, TINY)):
        assert json.loads((tmp_path / ".lock").read_text())["pid"] == os.getpid()


# --- a damaged run directory -----------------------------------------------------------------


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """One uninterrupted tiny run: (run dir, summary)."""
    run = tmp_path_factory.mktemp("tiny") / "run"
    return run, _optimize(run).summary


def _copy(run: Path, to: Path) -> Path:
    shutil.copytree(run, to)
    (to / RESULT).unlink()  # not finished: the learning runs, from the journal
    return to


_BAD_LINES = [
    b"garbage, not JSON\n",
    b"\xff\xfe\x00 binary\n",
    b"[" * 100_000 + b"\n",  # nested too deep for the JSON reader
    b'{"i": 1, "vector": [0.5, 0.5]}\n',  # missing keys
    b'{"i": 1, "vector": [0.5, 0.5], "valid": true, "outcome": "success", "events": {}, '
    b'"seconds": 0.1}\n',  # a vector of the wrong length, no events
    b'{"i": 1, "vector": ["a", 0.5, 0.5], "valid": true, "outcome": "success", '
    b'"events": {}, "seconds": 0.1}\n',
    b'{"i": 1, "vector": [0.5, 0.5, 0.5], "valid": "yes", "outcome": "success", '
    b'"events": {}, "seconds": 0.1}\n',
    b"42\n",
]


def test_garbage_and_malformed_lines_are_moved_aside_and_the_run_continues(tiny_run, tmp_path,
                                                                           caplog):
    ref_run, ref = tiny_run
    run = _copy(ref_run, tmp_path / "run")
    lines = (run / SIMULATIONS).read_bytes().splitlines(keepends=True)
    # bad lines among good ones, and a wrong type inside an otherwise good record
    good = json.loads(lines[5])
    good["events"][next(iter(good["events"]))] = ["yes", 0.1]
    bad = [*_BAD_LINES, (json.dumps(good) + "\n").encode()]
    mixed = lines[:3] + bad[:4] + lines[3:5] + bad[4:] + lines[6:]
    (run / SIMULATIONS).write_bytes(b"".join(mixed))
    with caplog.at_level(logging.WARNING, logger="rgmcad.runs.store"):
        resumed = _optimize(run).summary
    assert resumed["vector"] == ref["vector"] and resumed["probability"] == ref["probability"]
    assert resumed["simulated_now"] == 1  # the record whose event label was damaged
    assert (run / REJECTED).read_bytes() == b"".join(bad)
    kept = (run / SIMULATIONS).read_bytes().splitlines(keepends=True)
    assert kept[:len(lines) - 1] == lines[:5] + lines[6:]
    warnings = [r for r in caplog.records if r.levelno >= logging.WARNING]
    assert len(warnings) == 1 and REJECTED in warnings[0].getMessage()
    assert f"{len(bad)} line(s)" in warnings[0].getMessage()


def test_the_command_says_once_on_stderr_that_lines_were_moved_aside(small_run, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(small_run[0], run)
    with open(run / SIMULATIONS, "ab") as f:
        f.write(b"not a record\n")
    command = _optimize_command(run)
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and json.loads(done.stdout)["vector"] == small_run[1]["vector"]
    said = [line for line in done.stderr.splitlines() if REJECTED in line]
    assert len(said) == 1 and "1 line(s)" in said[0], done.stderr
    assert (run / REJECTED).read_bytes() == b"not a record\n"
    with RunStore(run, json.loads((run / SETTINGS).read_text())) as store:  # healed
        assert store.n_rejected == 0 and store.n_lines >= len(store.records) > 0


@pytest.mark.parametrize("damage", ["result garbage", "result missing", "result not a summary",
                                    "model garbage", "model missing"])
def test_a_finished_run_with_a_broken_result_or_model_is_recomputed_from_its_journal(
        tiny_run, tmp_path, damage):
    ref_run, ref = tiny_run
    run = tmp_path / "run"
    shutil.copytree(ref_run, run)
    target = run / (RESULT if damage.startswith("result") else "model.pkl")
    if damage.endswith("missing"):
        target.unlink()
    else:
        target.write_bytes(b"[1, 2]" if damage.endswith("summary") else b"\x80\x05garbage")
    done = _optimize(run)
    assert not done.finished_before
    assert done.summary["vector"] == ref["vector"]
    assert done.summary["simulated_now"] == 0  # every simulation replayed
    again = _optimize(run)  # healed: finished, with its model
    assert again.finished_before and again.summary["model_sha256"] == ref["model_sha256"]


def test_a_run_directory_without_its_settings_is_refused_not_remade(tiny_run, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(tiny_run[0], run)
    (run / SETTINGS).unlink()
    with pytest.raises(RunDirectoryError, match="settings.json: missing, but the directory"):
        _optimize(run)
    assert not (run / SETTINGS).exists()
    code, _, err = cli_output(["optimize", SIMPLE, "--budget", "small", "--run", str(run)])
    assert code == 2 and len(err.strip().splitlines()) == 1 and "settings.json" in err


def test_records_with_wrong_types_never_reach_the_learner(tmp_path):
    ident = run_identity("s", "0" * 64, 0, TINY)
    rows = [{"vector": [0.1, 0.2], "valid": True, "outcome": "success",
             "events": {"a": [True, 0.1]}, "seconds": 0.05}]
    for change in ({"valid": 1}, {"outcome": "maybe"}, {"outcome": "invalid"},
                   {"events": {"a": [1, 0.1]}}, {"events": {"a": [True, "late"]}},
                   {"events": {"b": [True, 0.1]}}, {"events": [1]}, {"seconds": -1},
                   {"seconds": None}, {"vector": [0.1, float("nan")]}, {"vector": [True, 0.2]},
                   {"vector": 0.1}):
        rows.append({**rows[0], **change})
    (tmp_path / SETTINGS).write_text(json.dumps(ident))
    (tmp_path / SIMULATIONS).write_text("".join(json.dumps(r) + "\n" for r in rows))
    with RunStore(tmp_path, ident, dimension=2, events=["a"]) as store:
        assert store.n_lines == 1 and store.n_rejected == len(rows) - 1
        assert store.lookup(np.array([0.1, 0.2])).label().success


# --- flags and places, before the work ---------------------------------------------------------


@pytest.fixture
def no_simulation(monkeypatch):
    """Fail if a command gets as far as starting its simulations."""
    def refuse(*args, **kwargs):
        raise AssertionError("simulations started")

    monkeypatch.setattr("rgmcad.runs.workflow.make_executor", refuse)


@pytest.mark.parametrize("argv, named", [
    (["optimize", SIMPLE, "--workers", "0"], "--workers"),
    (["optimize", SIMPLE, "--workers", "-3"], "--workers"),
    (["optimize", SIMPLE, "--workers", "100000"], "--workers"),
    (["optimize", SIMPLE, "--seed", "-1"], "--seed"),
    (["optimize", SIMPLE, "--seed", str(2**32)], "--seed"),
    (["optimize", SIMPLE, "--batch", "0"], "--batch"),
    (["optimize", SIMPLE, "--batch", "10001"], "--batch"),
    (["evaluate", SIMPLE, "--layout", "solved", "--workers", "0"], "--workers"),
    (["evaluate", SIMPLE, "--layout", "solved", "--rho-g", "--samples", "0"], "--samples"),
    (["evaluate", SIMPLE, "--layout", "solved", "--rho-g", "--samples", "1000000000"], "--samples"),
    (["evaluate", SIMPLE, "--layout", "solved", "--seed", "-5"], "--seed"),
])
def test_numbers_out_of_range_are_one_line_naming_the_flag(argv, named, no_simulation):
    code, out, err = cli_output(argv)
    assert code == 2 and not out
    assert len(err.strip().splitlines()) == 1 and named in err and " to " in err


def test_workers_within_the_range_are_accepted():
    from rgmcad.runs.checks import check_workers
    from rgmcad.runs.executor import max_workers

    assert check_workers(1) == 1 and check_workers(max_workers()) == max_workers()
    assert 1 <= max_workers() <= 256


def _unusable(tmp_path) -> dict[str, Path]:
    a_file = tmp_path / "a_file"
    a_file.write_text("not a folder")
    return {"under a file": a_file / "sub", "a file": a_file}


@pytest.mark.parametrize("case", ["under a file", "a file", "a NUL byte"])
def test_optimize_refuses_a_run_directory_it_cannot_use(tmp_path, case, no_simulation):
    run = {**_unusable(tmp_path), "a NUL byte": tmp_path / "a\0b"}[case]
    code, out, err = cli_output(["optimize", SIMPLE, "--budget", "small", "--run", str(run)])
    assert code == 2 and not out
    assert len(err.strip().splitlines()) == 1 and "--run" in err
    # the library, without the command's checks, refuses it too (it tries, as root as well)
    with pytest.raises(RunDirectoryError, match="cannot be used as a run directory"):
        _optimize(run)


NOT_ROOT = pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0,
                              reason="as root, a read-only folder can still be written")


@pytest.fixture
def read_only_folder(tmp_path):
    """A folder nobody but root can write into, writable again after the test."""
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o500)
    yield folder
    folder.chmod(0o700)


@NOT_ROOT
def test_optimize_refuses_a_read_only_run_directory(read_only_folder, no_simulation):
    run = read_only_folder
    code, _, err = cli_output(["optimize", SIMPLE, "--budget", "small", "--run", str(run)])
    assert code == 2 and len(err.strip().splitlines()) == 1 and "--run" in err
    with pytest.raises(RunDirectoryError, match="Permission denied"):  # the library tries
        RunStore(run, run_identity("s", "0" * 64, 0, TINY))


@pytest.mark.parametrize("case", ["under a file", "in a file", "in no folder", "a folder",
                                  "unknown format", "a NUL byte"])
def test_evaluate_refuses_a_plot_it_cannot_write_before_simulating(tmp_path, case,
                                                                   no_simulation):
    out = {"under a file": _unusable(tmp_path)["under a file"] / "rob.png",
           "in a file": _unusable(tmp_path)["a file"] / "rob.png",
           "in no folder": tmp_path / "missing" / "rob.png",
           "a folder": tmp_path, "unknown format": tmp_path / "rob.xyz",
           "a NUL byte": tmp_path / "r\0b.png"}[case]
    code, printed, err = cli_output(["evaluate", SIMPLE, "--layout", "solved", "--out", str(out)])
    assert code == 2 and not printed
    assert len(err.strip().splitlines()) == 1 and "--out" in err
    with pytest.raises(UsageError, match="plot"):  # the library checks its plot too
        evaluate_layout(SIMPLE, "solved", samples=1, plot=out)


@NOT_ROOT
def test_evaluate_refuses_a_read_only_folder_for_its_plot(read_only_folder, no_simulation):
    code, _, err = cli_output(["evaluate", SIMPLE, "--layout", "solved", "--out",
                         str(read_only_folder / "rob.png")])
    assert code == 2 and len(err.strip().splitlines()) == 1 and "--out" in err
