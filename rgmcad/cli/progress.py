"""Progress bars on stderr for the commands that run many simulations (a
:class:`~rgmcad.runs.workflow.RunProgress`). ``-q`` turns them off."""

from __future__ import annotations

import sys


class SimulationBar:
    """Stage, simulations and successes, counted as the run's summary counts them: each
    distinct layout once (the store hands out one record per layout, so a repeated or stored
    layout comes back as the same record), the verification stage included. ``replayed``:
    records read back from an earlier, interrupted call. The bar appears at the first report,
    so a finished run shows none.

    Parameters
    ----------
    desc : the first stage's name.
    count_tested : whether the layouts tested for validity are shown (``evaluate``).
    """

    def __init__(self, desc: str = "exploration", count_tested: bool = False,
                 enabled: bool = True):
        self.desc, self.count_tested, self.enabled = desc, count_tested, enabled
        self.bar = None
        self.seen: set[int] = set()
        self._records: list = []  # keeps the records alive, so their ids stay theirs
        self.simulations = self.successes = self.replayed = self.n_tested = 0
        self.builds = self.built_successes = 0

    def _start(self):
        if self.bar is None:
            from tqdm import tqdm

            self.bar = tqdm(desc=self.desc, unit="sim", file=sys.stderr, mininterval=0.5,
                            dynamic_ncols=True, disable=not self.enabled)
        return self.bar

    def stage(self, name: str, total: int | None = None) -> None:
        """A new stage; with ``total`` (its simulations, or at most so many) the bar counts
        the stage's simulations against it and shows the time left (at most, then); without,
        every simulation so far."""
        bar = self._start()
        if total is not None:
            bar.reset(total=total)
        elif bar.total is not None:  # back to counting every simulation of the run
            bar.reset()
            bar.total = None
            bar.update(self.simulations)
            self._postfix(bar)
        if name != self.desc:
            self.desc = name
            bar.set_description(name)

    def tested(self, n: int) -> None:
        if self.count_tested:
            self.n_tested += n
            self._postfix(self._start())

    def simulated(self, record, replayed: bool = False) -> None:
        from rgmcad.sim.run import Outcome

        bar = self._start()
        if id(record) in self.seen:
            return
        self.seen.add(id(record))
        self._records.append(record)
        self.simulations += 1
        self.successes += record.outcome is Outcome.SUCCESS
        self.replayed += replayed
        self._postfix(bar)
        bar.update(1)

    def built(self, record) -> None:
        """A build placed by hand: the stage's bar moves, the run's counts do not."""
        from rgmcad.sim.run import Outcome

        self.builds += 1
        self.built_successes += record.outcome is Outcome.SUCCESS
        bar = self._start()
        bar.set_postfix(works=self.built_successes, refresh=False)
        bar.update(1)

    def measured(self, figures: dict) -> None:
        """The headline as soon as it is known, above the bar (the rest follows)."""
        if "hand" in figures and self.enabled:
            from rgmcad.runs.hand_text import hand_headline

            self._start().write(f"{hand_headline(figures)}; the curve and the weak links "
                                "follow", file=sys.stderr)

    def _postfix(self, bar) -> None:
        shown = {"tested": self.n_tested} if self.count_tested else (
            {"replayed": self.replayed} if self.replayed else {})
        bar.set_postfix(successes=self.successes, **shown, refresh=False)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
