"""The live page's web server (aiohttp): fixed routes, a WebSocket that pushes the state to
every open page, and the file watcher that starts a new simulation on every save.

Routes are a fixed table (``/``, ``/live.js``, ``/live.css``, ``/view``: the viewer's page of
the last result, ``/state``: the state as JSON, ``/ws``): nothing in a
URL names a file, so no path can reach the file system; anything else is 404. The server
binds to 127.0.0.1 unless told otherwise; then it also refuses requests whose ``Host`` is
not a loopback name (a web page cannot reach it by a name of its own), and WebSocket
connections from another origin (a page elsewhere cannot drive it).
"""

from __future__ import annotations

import asyncio
import errno
import ipaddress
import json
import logging
import signal
import socket
import time
from collections.abc import Callable
from importlib import resources
from urllib.parse import urlsplit

from aiohttp import WSMsgType, web

from rgmcad.errors import UsageError
from rgmcad.live.files import Watcher, watched_files
from rgmcad.live.session import LiveOptions, Session

__all__ = ["serve", "bind", "make_app", "address", "DEBOUNCE"]

log = logging.getLogger(__name__)

DEBOUNCE = 0.05
"""Seconds of quiet after a file event before the files are read (an editor's save may be
a truncation, then a write)."""
MAX_MESSAGE = 64 * 1024
_ASSETS = {"/live.js": ("live.js", "application/javascript"),
           "/live.css": ("live.css", "text/css")}
_PAGE_POLICY = ("default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self' data:; "
                "connect-src 'self'; frame-src 'self'; frame-ancestors 'none'; base-uri 'none'; "
                "form-action 'none'")
# the viewer's page: inline scripts and styles, its modules imported from blob: URLs
_VIEW_POLICY = ("default-src 'none'; script-src 'unsafe-inline' blob:; style-src 'unsafe-inline'; "
                "img-src data: blob:; frame-ancestors 'self'; base-uri 'none'; form-action 'none'")
_WAITING = ("<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>waiting</title>"
            "</head><body><p>The first simulation is running...</p></body></html>")


def _asset(name: str) -> str:
    return resources.files("rgmcad.live").joinpath("assets", name).read_text(encoding="utf-8")


def _loopback(host: str) -> bool:
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return host == "localhost"


def _host_name(host: str) -> str | None:
    """The name in a ``Host`` header (``localhost:8767`` -> ``localhost``), None if garbled."""
    try:
        return urlsplit(f"//{host}").hostname
    except ValueError:
        return None


def address(sock: socket.socket) -> str:
    """The page's address on the socket it is served from."""
    host, port = sock.getsockname()[:2]
    return f"http://{f'[{host}]' if ':' in host else host}:{port}/"


def bind(host: str, port: int) -> socket.socket:
    """A listening socket on ``host:port`` (port 0: a free one), or one line saying why not."""
    try:
        family = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)[0][0]
    except socket.gaierror as exc:
        raise UsageError("--host", host, f"not an address of this machine ({exc.strerror})") from None
    try:
        return socket.create_server((host, port), family=family, backlog=64)
    except OSError as exc:
        if exc.errno == errno.EADDRINUSE:
            raise UsageError("--port", str(port), "in use by another program (another rgmcad "
                             "live?); choose another with --port N, or --port 0 for a free one"
                             ) from None
        if exc.errno == errno.EACCES:
            raise UsageError("--port", str(port), "not allowed here (ports below 1024 need "
                             "privileges); choose one from 1024 to 65535") from None
        raise UsageError("--host", host, f"cannot listen there ({exc.strerror})") from None


def make_app(session: Session, local: bool) -> web.Application:
    """The application: its routes, and the checks every request passes (``local``: the
    server listens on a loopback address only)."""

    @web.middleware
    async def guard(request: web.Request, handler):
        if local and _host_name(request.host) not in ("localhost", "127.0.0.1", "::1"):
            return web.Response(status=403, text="this server answers only to localhost")
        response = await handler(request)
        response.headers.setdefault("X-Content-Type-Options", "nosniff")
        response.headers.setdefault("Cache-Control", "no-store")
        return response

    async def page(request: web.Request) -> web.Response:
        return web.Response(text=_asset("live.html"), content_type="text/html",
                            headers={"Content-Security-Policy": _PAGE_POLICY})

    async def asset(request: web.Request) -> web.Response:
        name, kind = _ASSETS[request.path]
        return web.Response(text=_asset(name), content_type=kind)

    async def view(request: web.Request) -> web.Response:
        return web.Response(text=session.html or _WAITING, content_type="text/html",
                            headers={"Content-Security-Policy": _VIEW_POLICY,
                                     "X-Frame-Options": "SAMEORIGIN"})

    async def state(request: web.Request) -> web.Response:
        return web.json_response(session.state)

    async def websocket(request: web.Request) -> web.StreamResponse:
        origin = request.headers.get("Origin")
        if origin is not None and urlsplit(origin).netloc != request.host:
            return web.Response(status=403, text="WebSocket from another origin refused")
        ws = web.WebSocketResponse(heartbeat=30, max_msg_size=MAX_MESSAGE)
        await ws.prepare(request)
        session.sockets.add(ws)
        try:
            await ws.send_json(session.state)
            async for message in ws:
                if message.type != WSMsgType.TEXT:
                    continue
                try:
                    data = json.loads(message.data)
                except ValueError:
                    data = None
                await session.handle(data)
        finally:
            session.sockets.discard(ws)
        return ws

    app = web.Application(middlewares=[guard], client_max_size=MAX_MESSAGE)
    app.router.add_get("/", page)
    for path in _ASSETS:
        app.router.add_get(path, asset)
    app.router.add_get("/view", view)
    app.router.add_get("/state", state)
    app.router.add_get("/ws", websocket)
    return app


def serve(options: LiveOptions, ready: Callable[[str], None]) -> None:
    """Serve the live page of ``options.scenario`` until Ctrl-C (KeyboardInterrupt, raised
    once everything has stopped: the worker, the watcher, the pages) or SIGTERM (returns).
    ``ready(address)`` is called once the page can be opened. The worker is a spawned
    process, so a script calling this runs it under ``if __name__ == "__main__":``, as any
    user of :mod:`multiprocessing` (the ``rgmcad`` command does)."""
    sock = bind(options.host, options.port)
    try:
        asyncio.run(_serve(options, sock, ready))
    finally:
        sock.close()


async def _serve(options: LiveOptions, sock: socket.socket, ready) -> None:
    loop = asyncio.get_running_loop()
    session = Session(options)
    runner = web.AppRunner(make_app(session, _loopback(sock.getsockname()[0])),
                           handle_signals=False, access_log=None)
    await runner.setup()
    pending: list[asyncio.TimerHandle] = []
    first_seen: list[float] = []

    def settled() -> None:  # the files were quiet for DEBOUNCE s
        pending.clear()
        watcher.watch(watched_files(options.scenario))  # a drawing added or dropped
        session.files_changed(first_seen.pop())

    def changed(when: float) -> None:  # in the loop, for each file event
        first_seen[:] = first_seen[:1] or [when]
        for handle in pending:
            handle.cancel()
        pending[:] = [loop.call_later(DEBOUNCE, settled)]

    watcher = Watcher(lambda when: loop.call_soon_threadsafe(changed, when))
    watcher.watch(watched_files(options.scenario))
    watcher.start()
    stop = asyncio.Event()
    loop.add_signal_handler(signal.SIGTERM, stop.set)
    try:
        await web.SockSite(runner, sock).start()
        session.start()
        ready(address(sock))
        started = time.perf_counter()
        await stop.wait()
        log.info("stopped after %.0f s", time.perf_counter() - started)
    finally:
        loop.remove_signal_handler(signal.SIGTERM)
        # the watcher's thread takes up to a second to notice; the worker stops meanwhile
        await asyncio.gather(asyncio.to_thread(watcher.stop), session.close())
        await runner.cleanup()
