"""The run directory of ``rgmcad optimize``: all a run needs to continue after any interruption.

Files::

    settings.json      what the run is: scenario name and SHA-256 of its file, seed, the
                       LearningSettings (:func:`run_identity`). Written once; a later command
                       on the same folder must match it or is refused.
    simulations.jsonl  one line per finished simulation, written and flushed to the operating
                       system as it arrives and fsynced after each batch: {"i", "vector",
                       "valid", "outcome", "events": {name: [label, time]}, "seconds"}.
    simulations.rejected.jsonl
                       lines of simulations.jsonl that were not simulation records (damaged or
                       edited), moved aside when the store was opened.
    model.pkl          the trained success model (pickle of the learner's SPDModel; loading a
                       pickle can run code, so a run directory is trusted data).
    result.json        the summary, written last (atomically): its presence means "finished";
                       it records model.pkl's SHA-256.
    .lock              who has the directory open (:mod:`rgmcad.runs.lock`).

Why resuming gives the same result: the learner is deterministic given its seed, so a second
run asks for the same design vectors in the same order; :class:`RecordedProblem` answers those
already in ``simulations.jsonl`` from the file (keyed by the exact bytes of the vector) and
simulates only the rest. The simulator is deterministic too, so a replayed label equals the
label a new simulation would give. A ``kill -9`` loses at most the simulations in flight; a
line cut short by the kill has no final newline and is dropped (and cut off the file) when the
store is opened again. A power cut or system crash can lose the batch being simulated (what
was written but not yet fsynced): one fsync per batch, because one per simulation cost too
much (docs/decisions.md). A full disk stops the run with one line naming the file; a line
that did not fit is cut off again, so the same command resumes once there is room.

What can be healed is healed, with one warning (logged) each: a line that is not a
simulation record (garbage, a wrong type, a missing key, a vector of the wrong length) is
moved to ``simulations.rejected.jsonl`` and the run goes on without it (it is simulated
again if asked for); a damaged or missing ``result.json`` or ``model.pkl`` of a finished run
makes it "not finished", and the workflow recomputes it, replaying every simulation. What
cannot be checked is refused: a directory holding simulations but no ``settings.json``.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import pickle
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from rgmcad.errors import RunDirectoryError
from rgmcad.files import STORAGE_ERRORS, append_whole, cannot_write, reason, write_atomic, write_json_atomic
from rgmcad.runs.executor import map_blocks, parent_only
from rgmcad.runs.lock import DirectoryLock, LockedError
from rgmcad.runs.problem import SimRecord, simulate_layout_task, validity_task

__all__ = ["RunStore", "RecordedProblem", "run_identity", "identity_differences", "SETTINGS",
           "SIMULATIONS", "RESULT", "MODEL", "REJECTED"]

logger = logging.getLogger(__name__)

SETTINGS = "settings.json"
SIMULATIONS = "simulations.jsonl"
RESULT = "result.json"
MODEL = "model.pkl"
REJECTED = "simulations.rejected.jsonl"
FORMAT = 1

# LearningSettings fields outside a run's identity (speed only), and those added later at the
# value of the code before them (so older run directories stay resumable)
_NOT_IDENTITY = ("n_jobs",)
_ADDED_LATER = {"unmodelled_at": "start", "second_look": False, "exploration_stall_spacing": 0.0,
                "second_look_rounds": 1, "close_in_copies": 0, "exploration_move_share": 1.0,
                "exploration_staged": 0.0}


def run_identity(scenario_name: str, scenario_sha256: str, seed: int, settings,
                 parts: dict[str, str] | None = None) -> dict:
    """The content of ``settings.json`` for a run (JSON types only). ``parts``: the digest
    of each family of a ``--parts`` folder, when the run uses one (runs with the shipped
    families leave it out, as they always have)."""
    learning = {k: v for k, v in asdict(settings).items() if k not in _NOT_IDENTITY
                and _ADDED_LATER.get(k, ...) != v}
    identity = {"format": FORMAT, "scenario": scenario_name, "scenario_sha256": scenario_sha256,
                "seed": int(seed), "settings": learning}
    if parts is not None:
        identity["parts"] = dict(sorted(parts.items()))
    return json.loads(json.dumps(identity))


def _key(x) -> bytes:
    return np.ascontiguousarray(x, dtype=np.float64).tobytes()


class RunStore:
    """An open run directory (it owns the append-only simulation file and a lock).

    Parameters
    ----------
    directory : str or Path
        Created if missing.
    identity : dict
        :func:`run_identity` of the command; a directory whose ``settings.json`` differs is refused.
    dimension, events : optional
        The design space's dimension and the scenario's events: stored lines with another
        vector length or other events are moved aside.

    Raises
    ------
    RunDirectoryError
        The directory belongs to another run (other scenario, scenario file, seed or
        settings), holds simulations but no ``settings.json``, is used by another process
        (named), or cannot be created or written (a path under a file, a read-only folder).
    """

    def __init__(self, directory: str | Path, identity: Mapping[str, Any], *,
                 dimension: int | None = None, events: Sequence[str] | None = None):
        self.directory = Path(directory)
        self.identity = dict(identity)
        self.dimension, self.events = dimension, events
        self.records: dict[bytes, SimRecord] = {}
        self.n_lines = self.n_rejected = 0
        self.model_sha256: str | None = None
        self._lock = self._file = None
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
            self._lock = DirectoryLock(self.directory)
            parent_only(self._lock.fd)
            self._check_identity()
            self._load()
            self._file = open(self.directory / SIMULATIONS, "ab", buffering=0)  # noqa: SIM115
            parent_only(self._file.fileno())
        except LockedError as exc:
            raise RunDirectoryError(str(self.directory), "", str(exc)) from None
        except RunDirectoryError:
            self.close()
            raise
        except (OSError, ValueError) as exc:  # ValueError: a path with a NUL byte
            self.close()
            if isinstance(exc, OSError) and exc.errno in STORAGE_ERRORS and exc.filename:
                raise RunDirectoryError(exc.filename, "", cannot_write(exc)) from None
            raise RunDirectoryError(repr(str(self.directory)), "", "cannot be used as a run "
                                    f"directory ({reason(exc)}); choose another --run") from None
        except BaseException:
            self.close()
            raise

    # --- opening -----------------------------------------------------------------------------

    def _check_identity(self) -> None:
        path = self.directory / SETTINGS
        if not path.exists():
            held = [n for n in (SIMULATIONS, RESULT, MODEL) if (self.directory / n).exists()]
            if held:
                raise RunDirectoryError(str(path), "", f"missing, but the directory holds a run "
                                        f"({', '.join(held)}) that cannot be checked to be this "
                                        "one; restore settings.json, or choose another --run")
            write_json_atomic(path, self.identity)
            return
        try:
            stored = json.loads(path.read_text())
        except (OSError, ValueError) as exc:
            raise RunDirectoryError(str(path), "", f"unreadable ({exc}); remove the directory or "
                                "choose another --run") from None
        if stored == self.identity:
            return
        diffs = identity_differences(stored, self.identity)
        shown = "; ".join(f"{k}: run has {a!r}, command asks {b!r}" for k, a, b in diffs[:3])
        more = f" (and {len(diffs) - 3} more)" if len(diffs) > 3 else ""
        raise RunDirectoryError(str(path), diffs[0][0] if diffs else "",
                            f"this run directory was made for another run ({shown}{more}); "
                            "use the same scenario file, seed, budget and options (--set, "
                            "--batch, ...), or another --run DIR")

    def _load(self) -> None:
        path = self.directory / SIMULATIONS
        if not path.exists():
            return
        data = path.read_bytes()
        end = data.rfind(b"\n") + 1
        if end < len(data):  # a line cut short by an interruption: drop it from the file too
            logger.info("%s: dropping an unfinished last line (%d bytes)", path, len(data) - end)
            with open(path, "r+b") as f:
                f.truncate(end)
                f.flush()
                os.fsync(f.fileno())
        good, bad = [], []
        for n, line in enumerate(data[:end].splitlines(keepends=True), 1):
            if not line.strip():
                continue
            try:
                x, record = self._parse(line)
            except ValueError as exc:
                bad.append((n, line, str(exc)))
                continue
            good.append(line)
            self.records[_key(x)] = record
            self.n_lines += 1
        if bad:
            self._set_aside(path, good, bad)

    def _parse(self, line: bytes) -> tuple[np.ndarray, SimRecord]:
        """(vector, record) of a line of the journal, or ValueError saying what is wrong."""
        try:
            row = json.loads(line)
            record = SimRecord.from_json(row, self.events)
            vector = row["vector"]
            if not (isinstance(vector, list) and all(
                    isinstance(v, (int, float)) and not isinstance(v, bool) for v in vector)):
                raise ValueError("vector: expected a list of numbers")
            x = np.asarray(vector, dtype=float)
        except (ValueError, KeyError, TypeError, IndexError, RecursionError) as exc:
            raise ValueError(str(exc) if isinstance(exc, ValueError) else repr(exc)) from None
        if x.ndim != 1 or not np.all(np.isfinite(x)) or (
                self.dimension is not None and len(x) != self.dimension):
            raise ValueError(f"vector: expected {self.dimension or 'some'} finite numbers, "
                             f"got {len(x)}")
        return x, record

    def _set_aside(self, path: Path, good: list[bytes], bad: list) -> None:
        """Move the lines ``bad`` ((number, bytes, why)) to REJECTED, keep ``good``."""
        aside = self.directory / REJECTED
        with open(aside, "ab") as f:
            f.write(b"".join(line for _, line, _ in bad))
            f.flush()
            os.fsync(f.fileno())
        write_atomic(path, b"".join(good))  # after the copy: a crash between loses nothing
        n, _, why = bad[0]
        self.n_rejected = len(bad)
        logger.warning("%s: %d line(s) that are not simulation records (line %d: %s) moved to "
                       "%s; the run continues without them", path, len(bad), n, why[:120],
                       REJECTED)

    # --- simulations -------------------------------------------------------------------------

    def lookup(self, x) -> SimRecord | None:
        """The stored simulation of the exact design vector ``x`` (d,), if any."""
        return self.records.get(_key(x))

    def append(self, x, record: SimRecord, sync: bool = True) -> None:
        """Store one finished simulation: flushed to the operating system before returning
        (safe from a ``kill -9``), and fsynced (safe from a power cut) unless ``sync`` is
        False, for a caller that calls :meth:`sync` after a batch."""
        x = np.asarray(x, dtype=float)
        row = {"i": self.n_lines, "vector": x.tolist(), **record.to_json()}
        try:  # whole lines or none: a full disk leaves the journal as it was
            append_whole(self._file.fileno(), (json.dumps(row) + "\n").encode(), self._file.name)
            if sync:
                os.fsync(self._file.fileno())
        except OSError as exc:
            raise RunDirectoryError(self._file.name, "", cannot_write(exc)) from None
        self.records[_key(x)] = record
        self.n_lines += 1

    def sync(self) -> None:
        """fsync the simulations written so far."""
        try:
            os.fsync(self._file.fileno())
        except OSError as exc:
            raise RunDirectoryError(self._file.name, "", cannot_write(exc)) from None

    # --- results -----------------------------------------------------------------------------

    def write_result(self, result: Mapping) -> Path:
        path = self.directory / RESULT
        write_json_atomic(path, result)
        return path

    def read_result(self) -> dict | None:
        """A finished run's summary, or None: none, or ``result.json`` or the ``model.pkl`` it
        records damaged or missing (a warning says which; the run is then recomputed). The
        model is checked by its SHA-256, never unpickled."""
        path = self.directory / RESULT
        if not path.exists():
            return None
        try:
            result = json.loads(path.read_text())
            if not isinstance(result, dict) or not {"vector", "verified"} <= set(result):
                raise ValueError("not a run summary")
        except (OSError, ValueError) as exc:
            logger.warning("%s: unreadable (%s); recomputing the run from %s", path,
                           str(exc)[:120], SIMULATIONS)
            return None
        model = self.directory / MODEL
        try:
            digest = hashlib.sha256(model.read_bytes()).hexdigest()
        except OSError:
            digest = None
        if digest is None or result.get("model_sha256", digest) != digest:
            logger.warning("%s: %s; recomputing the run from %s", model,
                           "missing" if digest is None else "damaged (not the model the run "
                           "saved)", SIMULATIONS)
            return None
        return result

    def save_model(self, model) -> Path:
        """Pickle ``model`` to ``model.pkl``; :attr:`model_sha256` is then its SHA-256."""
        path = self.directory / MODEL
        data = pickle.dumps(model, protocol=pickle.HIGHEST_PROTOCOL)
        write_atomic(path, data)
        self.model_sha256 = hashlib.sha256(data).hexdigest()
        return path

    def close(self) -> None:
        if self._file is not None and not self._file.closed:
            parent_only(self._file.fileno(), keep=False)
            self._file.close()
        if self._lock is not None and self._lock.fd is not None:
            parent_only(self._lock.fd, keep=False)
            self._lock.release()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


# a key only one side has; its repr is what the refusal says ("run has nothing")
_MISSING = type("_Missing", (), {"__repr__": lambda self: "nothing"})()


def identity_differences(a, b, prefix: str = "") -> list[tuple[str, Any, Any]]:
    """Keys (dotted) whose values differ; a key only one side has counts, even against None."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in list(a) + [k for k in b if k not in a]:
            out += identity_differences(a.get(k, _MISSING), b.get(k, _MISSING), f"{prefix}{k}.")
        return out
    return [] if a == b else [(prefix.rstrip("."), a, b)]


class RecordedProblem:
    """A :class:`~rgmcad.learning.oracles.Problem` that answers from a :class:`RunStore`
    and runs what it lacks on an executor, storing each simulation as it finishes.

    :meth:`submit` starts a batch and returns at once, so the learner can draw the next
    batch meanwhile; batches are stored in the order they are waited for, which is the
    order they were submitted. While any batch is in flight, :meth:`validity` tests here
    instead of queueing behind the simulations in the pool.

    Parameters
    ----------
    problem : ScenarioProblem
        The problem in this process (validity tests here, penetration, the causal graph).
    store : RunStore
    executor : Executor
        See :mod:`rgmcad.runs.executor`; its context (the problem's
        :class:`~rgmcad.runs.problem.ScenarioContext` in each process) simulates and tests
        validity: ``make_executor(workers, problem.context)``.
    on_simulation : callable, optional
        ``on_simulation(record, replayed)`` after every simulation, stored or new.

    Attributes
    ----------
    n_replayed, n_simulated : int
        Simulations answered from the store / run now.
    """

    def __init__(self, problem, store: RunStore, executor,
                 on_simulation: Callable[[SimRecord, bool], None] | None = None):
        self.problem = problem
        self.store = store
        self.executor = executor
        self.on_simulation = on_simulation
        self.dimension = problem.dimension
        self.event_parents, self.any_joins = problem.event_parents, problem.any_joins
        self.event_dimensions = getattr(problem, "event_dimensions", None)  # exploration in stages
        self.n_replayed = 0
        self.n_simulated = 0
        self._in_flight = 0  # batches submitted and not yet waited for
        self._valid: set[bytes] = set()  # layouts found valid here: not tested again

    def validity(self, X: np.ndarray) -> np.ndarray:
        # While simulations are in flight the pool is busy and this process is waiting:
        # testing here costs a millisecond, in the pool a wait for the batch ahead.
        X = np.atleast_2d(np.asarray(X, dtype=float))
        if self._in_flight or min(len(X), self.executor.workers) <= 1:
            ok = np.asarray(self.problem.validity(X), dtype=bool)
        else:
            ok = map_blocks(self.executor, validity_task, X)
        self._valid.update(_key(x) for x in X[ok])
        return ok

    def penetration(self, x: np.ndarray) -> float:
        return self.problem.penetration(x)

    def simulate_records(self, X: np.ndarray) -> list[SimRecord]:
        """One record per row of ``X`` (n, d): stored ones replayed, the others simulated
        (a vector repeated in ``X`` is simulated once)."""
        return self.submit_records(X)()

    def submit_records(self, X: np.ndarray) -> Callable[[], list[SimRecord]]:
        """Start what :meth:`simulate_records` does; the returned ``wait()`` stores the new
        simulations as they finish and gives the records. Batches must be waited for in the
        order they were submitted (a vector also in an earlier batch still in flight is
        simulated again, with the same result)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        records: list[SimRecord | None] = [self.store.lookup(x) for x in X]
        todo: dict[bytes, int] = {}  # first row of each missing vector
        for i, r in enumerate(records):
            if r is None:
                todo.setdefault(_key(X[i]), i)
        rows = list(todo.values())
        results = self.executor.map_context(
            simulate_layout_task, [(X[i], _key(X[i]) in self._valid, self._draw(X[i]))
                                   for i in rows])
        self._in_flight += 1

        def wait() -> list[SimRecord]:
            try:
                for i, record in zip(rows, results, strict=True):
                    self.store.append(X[i], record, sync=False)
                    self.n_simulated += 1
                    if self.on_simulation is not None:
                        self.on_simulation(record, False)
            finally:
                self._in_flight -= 1
                if rows:
                    self.store.sync()
            for i, r in enumerate(records):
                if r is None:
                    records[i] = self.store.lookup(X[i])
                    if i == todo[_key(X[i])]:
                        continue
                self.n_replayed += 1
                if self.on_simulation is not None:
                    self.on_simulation(records[i], True)
            return records

        return wait

    physics_noise = None  # (PhysicsRanges, seed): each new layout with its own physical draw
    physics_worlds = None  # a tuple of physical worlds: each new layout labelled by its worst

    def _draw(self, x):  # the physics of a new layout's simulation (None: the scenario's)
        if self.physics_noise is None:
            return self.physics_worlds  # None, or a tuple of worlds
        from rgmcad.scene.perturbation import layout_draw
        return layout_draw(*self.physics_noise, x)

    def submit(self, X: np.ndarray) -> Callable[[], list]:
        """:meth:`submit_records` giving labels."""
        wait = self.submit_records(X)
        return lambda: [r.label() for r in wait()]

    def simulate(self, X: np.ndarray):
        return [r.label() for r in self.simulate_records(X)]
