"""A pybullet physics server of one's own: the engine a :class:`~rgmcad.sim.world.World` is
built in.

pybullet keeps its worlds in physics servers named by a client id; every call takes
``physicsClientId``, and a call that forgets it goes to client 0. An :class:`Engine` is one
DIRECT server whose functions come bound to its id (the ``pybullet_utils.bullet_client``
pattern): ``engine.stepSimulation()`` is ``pb.stepSimulation(physicsClientId=engine.cid)``.

A world resets its engine when it is built (a fresh run, which restoring a saved state is
not: stale contact caches), so an engine holds one live world at a time. Connecting costs
about as much as a short simulation (docs/decisions.md, "Simulation and runs stages"), so a caller that
simulates many layouts (a worker process, :class:`~rgmcad.runs.problem.ScenarioContext`)
keeps one engine and hands it to each world; a world given none makes its own and closes
it with itself.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import os
import sys
import types
import weakref


def _import_pybullet():
    """``import pybullet`` with file descriptors 1 and 2 silenced: its C code prints a banner
    ("pybullet build time: ...") when imported, past ``sys.stdout``/``sys.stderr``, which would
    break ``--json`` output and one-line errors. Every module of :mod:`rgmcad.sim` takes
    pybullet from here (``from rgmcad.sim.engine import pb``), so this is the first import."""
    sys.stdout.flush()
    sys.stderr.flush()
    try:
        saved = [os.dup(1), os.dup(2)]
    except OSError:  # no standard streams to protect
        import pybullet

        return pybullet
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 1)
        os.dup2(null, 2)
        import pybullet

        with contextlib.suppress(OSError, TypeError, AttributeError):  # no C library: no buffer
            ctypes.CDLL(None).fflush(None)  # what C buffered (a pipe is block-buffered) goes too
    finally:
        for fd, copy in zip((1, 2), saved, strict=True):
            os.dup2(copy, fd)
            os.close(copy)
        os.close(null)
    return pybullet


pb = _import_pybullet()


_RENDERER = "tinyRendererPlugin"
"""pybullet's software renderer, a plugin linked into every DIRECT server."""


def _disconnect(cid: int) -> None:
    if pb.isConnected(cid):
        pb.disconnect(cid)


class Engine:
    """One pybullet DIRECT client; its pybullet functions are attributes bound to it.

    Disconnected by :meth:`close` (or ``with Engine() as engine:``), else when it is
    garbage-collected.

    Parameters
    ----------
    renderer : keep pybullet's built-in renderer (``getCameraImage``). An engine that only
        simulates goes without: the renderer makes a visual mesh of every collision shape as
        bodies are created, most of the cost of building a world (an infinite plane alone
        took 3 ms); physics does not depend on it.

    Attributes
    ----------
    cid : int
        The client id.
    """

    def __init__(self, renderer: bool = True):
        self.cid = pb.connect(pb.DIRECT)
        self._close = weakref.finalize(self, _disconnect, self.cid)
        self._holder = None  # weak reference to the live world built in this engine
        self.renderer = renderer
        if not renderer:  # the static plugin's id, then unloaded: no visual shapes are made
            plugin = pb.loadPlugin(_RENDERER, physicsClientId=self.cid)
            if plugin >= 0:
                pb.unloadPlugin(plugin, physicsClientId=self.cid)

    def __getattr__(self, name: str):
        function = getattr(pb, name)
        if not isinstance(function, types.BuiltinFunctionType):
            raise AttributeError(f"pybullet.{name} is not a function of an engine")
        bound = functools.partial(function, physicsClientId=self.cid)
        setattr(self, name, bound)  # found directly from now on
        return bound

    @property
    def connected(self) -> bool:
        return self._close.alive and bool(pb.isConnected(self.cid))

    def hold(self, world) -> None:
        """Make ``world`` the engine's live world (a world calls this as it is built).

        Raises
        ------
        RuntimeError
            Another world built here is still open: it would be reset under its user.
        """
        if not self._close.alive:
            raise RuntimeError("this engine is closed")
        holder = self._holder() if self._holder is not None else None
        if holder is not None and holder is not world and not holder.closed:
            raise RuntimeError("this engine holds a live world; close that world first, or "
                               "give each World its own Engine")
        self._holder = weakref.ref(world)

    def release(self, world) -> None:
        """``world`` is closed: the engine may take another."""
        if self._holder is not None and self._holder() is world:
            self._holder = None

    def close(self) -> None:
        self._close()

    def __enter__(self) -> Engine:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
