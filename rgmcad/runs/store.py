"""The run directory of ``rgmcad optimize``: everything a run needs to continue after any
interruption.

Files::

    settings.json      what the run is: scenario name and SHA-256 of its file, seed, every
                       LearningSettings field. Written once; a later command on the same folder
                       must match it or is refused.
    simulations.jsonl  one line per finished simulation, written and flushed to the operating
                       system as it arrives and fsynced after each batch: {"i", "vector",
                       "valid", "outcome", "events": {name: [label, time]}, "seconds"}.
    model.pkl          the trained success model (pickle of the learner's SPDModel).
    result.json        the summary, written last (atomically): its presence means "finished".

Why resuming gives the same result: the learner is deterministic given its seed, so a second
run asks for the same design vectors in the same order; :class:`RecordedProblem` answers those
already in ``simulations.jsonl`` from the file (keyed by the exact bytes of the vector) and
simulates only the rest. The simulator is deterministic too, so a replayed label equals the
label a new simulation would give. A ``kill -9`` loses at most the simulations in flight; a
line cut short by the kill has no final newline and is dropped (and cut off the file) when the
store is opened again. A power cut or system crash can lose the batch being simulated (what
was written but not yet fsynced): one fsync per batch, because one per simulation cost too
much (docs/decisions.md).
"""

from __future__ import annotations

import fcntl
import json
import logging
import os
import pickle
from collections.abc import Callable, Mapping
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from rgmcad.errors import RunDirectoryError
from rgmcad.runs.executor import map_blocks
from rgmcad.runs.problem import SimRecord, simulate_task, validity_task

__all__ = ["RunStore", "RecordedProblem", "run_identity", "SETTINGS", "SIMULATIONS", "RESULT",
           "MODEL"]

logger = logging.getLogger(__name__)

SETTINGS = "settings.json"
SIMULATIONS = "simulations.jsonl"
RESULT = "result.json"
MODEL = "model.pkl"
FORMAT = 1

# LearningSettings fields that change how fast a run goes, never what it finds.
_NOT_IDENTITY = ("n_jobs",)


def run_identity(scenario_name: str, scenario_sha256: str, seed: int, settings) -> dict:
    """The content of ``settings.json`` for a run (JSON types only)."""
    learning = {k: v for k, v in asdict(settings).items() if k not in _NOT_IDENTITY}
    return json.loads(json.dumps({
        "format": FORMAT, "scenario": scenario_name, "scenario_sha256": scenario_sha256,
        "seed": int(seed), "settings": learning,
    }))


def _key(x) -> bytes:
    return np.ascontiguousarray(x, dtype=np.float64).tobytes()


def _write_atomic(path: Path, data: bytes) -> None:
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


class RunStore:
    """An open run directory (it owns the append-only simulation file and a lock).

    Parameters
    ----------
    directory : str or Path
        Created if missing.
    identity : dict
        :func:`run_identity` of the command. A directory whose ``settings.json`` differs is
        refused.

    Raises
    ------
    RunDirectoryError
        The directory belongs to another run (other scenario, scenario file, seed or
        settings), or another process has it open.
    """

    def __init__(self, directory: str | Path, identity: Mapping[str, Any]):
        self.directory = Path(directory)
        self.directory.mkdir(parents=True, exist_ok=True)
        self._lock = open(self.directory / ".lock", "w")
        try:
            fcntl.flock(self._lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            self._lock.close()
            raise RunDirectoryError(str(self.directory), "", "another rgmcad process is using this "
                                "run directory; wait for it or choose another --run") from None
        self.identity = dict(identity)
        self._check_identity()
        self.records: dict[bytes, SimRecord] = {}
        self.n_lines = 0
        self._load()
        self._file = open(self.directory / SIMULATIONS, "ab")

    # --- opening -----------------------------------------------------------------------------

    def _check_identity(self) -> None:
        path = self.directory / SETTINGS
        if not path.exists():
            _write_atomic(path, (json.dumps(self.identity, indent=1) + "\n").encode())
            return
        try:
            stored = json.loads(path.read_text())
        except (OSError, ValueError) as exc:
            raise RunDirectoryError(str(path), "", f"unreadable ({exc}); remove the directory or "
                                "choose another --run") from None
        if stored == self.identity:
            return
        diffs = _differences(stored, self.identity)
        shown = "; ".join(f"{k}: run has {a!r}, command asks {b!r}" for k, a, b in diffs[:3])
        more = f" (and {len(diffs) - 3} more)" if len(diffs) > 3 else ""
        raise RunDirectoryError(str(path), diffs[0][0] if diffs else "",
                            f"this run directory was made for another run ({shown}{more}); "
                            "use the same scenario file, seed and budget, or another --run DIR")

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
        for n, line in enumerate(data[:end].splitlines(), 1):
            if not line.strip():
                continue
            try:
                row = json.loads(line)
                x = np.asarray(row["vector"], dtype=float)
                record = SimRecord.from_json(row)
            except (ValueError, KeyError, TypeError, IndexError) as exc:
                raise RunDirectoryError(str(path), f"line {n}", f"not a simulation record ({exc}); "
                                    "the file was edited or damaged") from None
            self.records[_key(x)] = record
            self.n_lines += 1

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
        self._file.write((json.dumps(row) + "\n").encode())
        self._file.flush()
        if sync:
            os.fsync(self._file.fileno())
        self.records[_key(x)] = record
        self.n_lines += 1

    def sync(self) -> None:
        """fsync the simulations written so far."""
        os.fsync(self._file.fileno())

    # --- results -----------------------------------------------------------------------------

    @property
    def finished(self) -> bool:
        return (self.directory / RESULT).exists()

    def write_result(self, result: Mapping) -> Path:
        path = self.directory / RESULT
        _write_atomic(path, (json.dumps(result, indent=1) + "\n").encode())
        return path

    def read_result(self) -> dict:
        return json.loads((self.directory / RESULT).read_text())

    def save_model(self, model) -> Path:
        path = self.directory / MODEL
        _write_atomic(path, pickle.dumps(model, protocol=pickle.HIGHEST_PROTOCOL))
        return path

    def close(self) -> None:
        if not self._file.closed:
            self._file.close()
        if not self._lock.closed:
            self._lock.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class _Missing:
    def __repr__(self) -> str:
        return "nothing"


_MISSING = _Missing()


def _differences(a, b, prefix: str = "") -> list[tuple[str, Any, Any]]:
    """Keys (dotted) whose values differ between two JSON objects; a key only one of them
    has counts even when the other side's value is None."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in list(a) + [k for k in b if k not in a]:
            out += _differences(a.get(k, _MISSING), b.get(k, _MISSING), f"{prefix}{k}.")
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
        self.event_parents = problem.event_parents
        self.any_joins = problem.any_joins
        self.n_replayed = 0
        self.n_simulated = 0
        self._in_flight = 0  # batches submitted and not yet waited for

    def validity(self, X: np.ndarray) -> np.ndarray:
        # While simulations are in flight the pool is busy and this process is waiting:
        # testing here costs a millisecond, in the pool a wait for the batch ahead.
        X = np.atleast_2d(np.asarray(X, dtype=float))
        if self._in_flight or min(len(X), self.executor.workers) <= 1:
            return np.asarray(self.problem.validity(X), dtype=bool)
        return map_blocks(self.executor, validity_task, X)

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
        results = self.executor.map_context(simulate_task, [X[i] for i in rows])
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

    def submit(self, X: np.ndarray) -> Callable[[], list]:
        """:meth:`submit_records` giving labels."""
        wait = self.submit_records(X)
        return lambda: [r.label() for r in wait()]

    def simulate(self, X: np.ndarray):
        return [r.label() for r in self.simulate_records(X)]
