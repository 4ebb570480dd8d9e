"""A real ``rgmcad live`` for tests: the command started as a subprocess on a copy of a
scenario, on a free port, with its state read over HTTP and its WebSocket spoken with
aiohttp's client (tests/test_live.py, tests/test_live_browser.py)."""

from __future__ import annotations

import asyncio
import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
import urllib.request
from pathlib import Path

from tests._support import popen_as_terminal

ROOT = Path(__file__).resolve().parent.parent
SIMPLE = ROOT / "scenarios" / "simple.toml"
TRACK = "pose = { x = -0.1, z = 0.1, roll = 30 }"
"""The line of simple.toml that places the track (its initial layout succeeds)."""
FAILING = "pose = { x = -0.1, z = 0.1, roll = 60 }"
"""... and one that fails (the last domino does not topple)."""
BROKEN = "\n[objects.track\n"
"""Appended to the file: not TOML any more."""


class Server:
    """``rgmcad live COPY --no-browser --port 0 ARGS`` in ``folder``, started and ready."""

    def __init__(self, folder: Path, *args: str, scenario: Path = SIMPLE, timeout: float = 60):
        self.file = folder / scenario.name
        if self.file != scenario:
            shutil.copy(scenario, self.file)
        self.original = self.file.read_text()
        self.proc = popen_as_terminal(  # Ctrl-C stops it however the tests were started
            [sys.executable, "-m", "rgmcad.cli", "live", str(self.file), "--no-browser",
             "--port", "0", *args], cwd=folder, stdout=subprocess.PIPE,
            stderr=subprocess.PIPE, text=True)
        self.out: list[str] = []
        self.err: list[str] = []
        for stream, lines in ((self.proc.stdout, self.out), (self.proc.stderr, self.err)):
            threading.Thread(target=lambda s=stream, ls=lines: ls.extend(iter(s.readline, "")),
                             daemon=True).start()
        deadline = time.monotonic() + timeout
        while not self.out:
            assert self.proc.poll() is None, "".join(self.err)[-3000:]
            assert time.monotonic() < deadline, "no address printed"
            time.sleep(0.02)
        self.url = self.out[0].split(" at ")[1].split()[0]
        self.ready = self.wait(lambda s: s.get("view", 0) >= 1 and not s["busy"], timeout)

    def state(self) -> dict:
        with urllib.request.urlopen(self.url + "state", timeout=10) as r:
            return json.loads(r.read())

    def wait(self, ok, timeout: float = 30) -> dict:
        """The first state that ``ok(state)`` accepts."""
        deadline = time.monotonic() + timeout
        while True:
            s = self.state()
            if ok(s):
                return s
            assert time.monotonic() < deadline, s
            assert self.proc.poll() is None, "".join(self.err)[-3000:]
            time.sleep(0.02)

    def write(self, text: str) -> dict:
        """Save the scenario as ``text`` (in place, as an editor does); the state after it."""
        before = self.state()["generation"]
        self.file.write_text(text)
        return self.wait(lambda s: s["generation"] > before and not s["busy"])

    def edit(self, old: str, new: str) -> dict:
        return self.write(self.original.replace(old, new))

    def talk(self, messages: list[dict], until=None, timeout: float = 60,
             origin: str | None = None) -> list[dict]:
        """Open the WebSocket, send ``messages``, and read states until ``until(state)``."""
        import aiohttp

        async def go():
            headers = {"Origin": origin} if origin else {}
            async with aiohttp.ClientSession() as s, s.ws_connect(self.url + "ws",
                                                                  headers=headers) as ws:
                states = [await ws.receive_json(timeout=timeout)]
                for m in messages:
                    await ws.send_json(m)
                while until is not None and not until(states[-1]):
                    states.append(await ws.receive_json(timeout=timeout))
                return states

        return asyncio.run(asyncio.wait_for(go(), timeout))

    def stop(self, timeout: float = 20) -> tuple[int, str, str]:
        """Ctrl-C; (exit status, stdout, stderr)."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
        try:
            code = self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:  # fail, leaving nothing behind
            os.killpg(self.proc.pid, signal.SIGKILL)
            raise
        time.sleep(0.1)  # the reader threads take the last lines
        return code, "".join(self.out), "".join(self.err)
