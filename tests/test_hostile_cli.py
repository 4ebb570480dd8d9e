"""What a hostile user gives the CLI, and what they get back: one line naming the flag or file,
what is allowed, exit status 2, within seconds, nothing lost. Each class of bad input is tried
with a few hand-picked cases and a generated corpus (fixed seeds; counts in ``CASES``)."""

from __future__ import annotations

import errno
import random
import socket
import threading
import time
from pathlib import Path

import pytest

from tests._support import cli_output

CASES = 14
"""Generated cases per class and kind."""


def refused(argv, *names, within: float = 5.0) -> str:
    """``rgmcad ARGV`` refused: exit status 2, one line on stderr naming ``names``, no
    traceback, within ``within`` seconds; the line."""
    start = time.perf_counter()
    code, out, err = cli_output(argv)
    took = time.perf_counter() - start
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, (argv, code, err[-2000:])
    assert "Traceback" not in err and lines[0].startswith("rgmcad: error: "), err
    for name in names:
        assert name in lines[0], (name, lines[0])
    assert took < within, (argv, took)
    return lines[0]


# --- 1. --scheduler ----------------------------------------------------------------------------


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


_BAD_PARTS = {
    "scheme": ["bogus", "http", "ftp", "tcpp", "", "tcp:", "1", "ücx", "t cp"],
    "host": ["", " ", "my cluster", "a..b", "-x", "x" * 70, "host\x00", "[zz]", "::1", "a/b",
             "\u202ehost", "h\tost", "[::1"],
    "port": ["", "0", "65536", "99999", "-1", "abc", "\u0663\u0664", "8786/x", "87 86", "1e3"],
}


def _malformed(rng: random.Random) -> str:
    """A scheduler address with one or two defects on a good base."""
    scheme, host, port = rng.choice(["tcp", "tls", "ws"]), rng.choice(["10.0.0.5", "node-1"]), "8786"
    for part in rng.sample(sorted(_BAD_PARTS), rng.choice([1, 1, 2])):
        value = rng.choice(_BAD_PARTS[part])
        scheme, host, port = (value if part == "scheme" else scheme,
                              value if part == "host" else host, value if part == "port" else port)
    shape = rng.choice(["{s}://{h}:{p}", "{s}://{h}:{p}", "{h}:{p}", "{s}//{h}:{p}", "{s}://{h}"])
    if shape in ("{h}:{p}",) and host in ("10.0.0.5", "node-1") and port == "8786":
        port = "0"  # a bare HOST:PORT is a tcp address: keep a defect
    if shape == "{s}://{h}:{p}" and scheme in ("tcp", "tls", "ws") and host in (
            "10.0.0.5", "node-1") and port == "8786":
        host = "my cluster"
    return shape.format(s=scheme, h=host, p=port)


def _malformed_corpus() -> list[str]:
    rng = random.Random(1)
    extra = ["", "local:0", "local:-1", "local:x", f"local:{10**6}", "LOCAL:", "local: 2",
             "my cluster", "bogus://x", "tcp://host:8786 extra"]
    return extra + [_malformed(rng) for _ in range(CASES)]


@pytest.mark.parametrize("address", _malformed_corpus())
def test_a_scheduler_address_of_another_form_is_refused_at_once(address):
    line = refused(["evaluate", "simple", "--layout", "initial", "--scheduler", address],
                   "--scheduler", within=2.0)
    assert "expected" in line or "needs" in line


def test_a_malformed_rgmcad_scheduler_is_refused_naming_the_variable(monkeypatch):
    monkeypatch.setenv("RGMCAD_SCHEDULER", "my cluster")
    refused(["evaluate", "simple", "--layout", "initial"], "RGMCAD_SCHEDULER", within=2.0)


def _well_formed_nobody_home(rng: random.Random) -> str:
    port = _closed_port()
    host = rng.choice(["127.0.0.1", "localhost", "LOCALHOST", "127.0.0.1."])
    return rng.choice(["tcp://{h}:{p}", "TCP://{h}:{p}", "{h}:{p}", "ws://{h}:{p}"]).format(
        h=host, p=port)


def test_a_scheduler_address_where_nothing_listens_is_one_line_at_once():
    from rgmcad.errors import RgmcadError
    from rgmcad.runs.executor import make_executor, scheduler_from_env

    rng = random.Random(2)
    for _ in range(CASES):
        address = _well_formed_nobody_home(rng)
        start = time.perf_counter()
        with pytest.raises(RgmcadError) as caught:
            make_executor(1, scheduler=scheduler_from_env(address))
        assert time.perf_counter() - start < 2.0, address
        message = str(caught.value)
        assert message.startswith("--scheduler: ") and "no Dask scheduler answers there" in message
        assert "\n" not in message


class _Server:
    """A TCP server on 127.0.0.1 that answers each connection with ``reply(rng)`` (None:
    never answers, keeps the connection open) and closes it."""

    def __init__(self, reply, seed: int = 0):
        self.reply, self.rng = reply, random.Random(seed)
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(16)
        self.address = f"tcp://127.0.0.1:{self.sock.getsockname()[1]}"
        self.held: list[socket.socket] = []
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self):
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            data = self.reply(self.rng)
            if data is None:
                self.held.append(conn)
                continue
            try:
                conn.sendall(data)
            except OSError:
                pass
            conn.close()

    def close(self):
        self.sock.close()
        for conn in self.held:
            conn.close()


def _garbage(rng: random.Random) -> bytes:
    kind = rng.choice(["random", "http", "huge", "empty", "frames"])
    if kind == "http":
        return b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n"
    if kind == "huge":
        return (2**62).to_bytes(8, "little") + rng.randbytes(rng.randrange(1, 64))
    if kind == "empty":
        return b""
    if kind == "frames":
        return (1).to_bytes(8, "little") + (8).to_bytes(8, "little") + rng.randbytes(8)
    return rng.randbytes(rng.randrange(1, 512))


def test_something_that_is_no_scheduler_is_one_line_at_once():
    from rgmcad.errors import RgmcadError
    from rgmcad.runs.dask_executor import DaskExecutor

    server = _Server(_garbage, seed=3)
    try:
        for _ in range(CASES):
            start = time.perf_counter()
            with pytest.raises(RgmcadError) as caught:
                DaskExecutor(server.address)
            assert time.perf_counter() - start < 4.0
            assert str(caught.value).startswith(f"--scheduler: {server.address}: ")
            assert "\n" not in str(caught.value)
    finally:
        server.close()


def test_a_host_that_never_answers_is_one_line_within_seconds(tmp_path):
    server = _Server(lambda rng: None)  # connects, then silence: as a firewall that drops
    try:
        line = refused(["evaluate", "simple", "--layout", "initial", "--out",
                        str(tmp_path / "hand.png"), "--scheduler", server.address],
                       "--scheduler", server.address, "within 3 s", within=5.0)
    finally:
        server.close()
    assert "no Dask scheduler answers there" in line


def test_the_schemes_checked_are_those_of_dask():
    from distributed.comm.registry import backends

    from rgmcad.runs.executor import SCHEDULER_SCHEMES

    assert set(backends) == set(SCHEDULER_SCHEMES)


# --- 2. verify-print on degenerate images --------------------------------------------------------


def _image_bytes(rng: random.Random, folder) -> tuple[str, bytes]:
    """(file name, content) of an image of a random degenerate shape, depth, channels and
    content, or the bytes of a good one damaged."""
    import io

    import numpy as np
    from PIL import Image

    gen = np.random.default_rng(rng.randrange(2**32))
    h, w = (rng.choice([1, 2, 31, 32, 33, 64, 120, 400, 2500]) for _ in range(2))
    if h * w > 300_000:
        h = 32
    kind = rng.choice(["L", "L16", "I", "F", "LA", "RGB", "RGBA", "1", "CMYK"])
    fill = rng.choice(["zeros", "max", "noise", "checker"])
    top = {"L16": 65535, "I": 2**31 - 1, "F": 1e30, "1": 1}.get(kind, 255)
    shape = (h, w, {"LA": 2, "RGB": 3, "RGBA": 4, "CMYK": 4}.get(kind, 1))
    if fill == "zeros":
        a = np.zeros(shape)
    elif fill == "max":
        a = np.full(shape, float(top))
    elif fill == "noise":
        a = gen.uniform(-top if kind in ("I", "F") else 0, top, shape)
    else:
        a = ((np.indices(shape[:2]).sum(0) // 4) % 2 * top)[..., None].repeat(shape[2], 2)
    a = a[..., 0] if shape[2] == 1 else a
    dtype = {"L16": np.uint16, "I": np.int32, "F": np.float32}.get(kind, np.uint8)
    mode = {"L16": "I;16", "1": "L"}.get(kind, kind)
    im = Image.fromarray(a.astype(dtype), mode=None if kind in ("I", "F", "L16") else mode)
    if kind == "1":
        im = im.convert("1")
    fmt = "TIFF" if kind in ("I", "F", "CMYK") else rng.choice(["PNG", "PNG", "TIFF"])
    buf = io.BytesIO()
    im.save(buf, format=fmt)
    data = buf.getvalue()
    damage = rng.choice(["none"] * 5 + ["truncate", "flip", "zero", "text"])
    if damage == "truncate":
        data = data[:rng.randrange(0, len(data))]
    elif damage == "flip":
        b = bytearray(data)
        for _ in range(rng.randrange(1, 20)):
            b[rng.randrange(len(b))] = rng.randrange(256)
        data = bytes(b)
    elif damage == "zero":
        data = b""
    elif damage == "text":
        data = b"a text file named like an image\n"
    name = f"{kind}-{h}x{w}-{fill}-{damage}.{'png' if fmt == 'PNG' else 'tif'}"
    return name, data


@pytest.mark.parametrize("seed", range(CASES))
def test_verify_print_refuses_a_degenerate_image_in_one_line(seed, tmp_path):
    name, data = _image_bytes(random.Random(seed), tmp_path)
    image = tmp_path / name
    image.write_bytes(data)
    line = refused(["verify-print", str(image)], str(image))
    assert any(w in line for w in ("too small", "cannot read", "no template marks",
                                   "million pixels")), line


@pytest.mark.parametrize("shape", [(1, 1), (1, 20000), (20000, 1), (31, 4000), (2, 2)])
def test_an_image_too_thin_for_a_mark_says_so(shape, tmp_path):
    import numpy as np
    from PIL import Image

    image = tmp_path / "thin.png"
    Image.fromarray(np.full(shape, 255, np.uint8)).save(image)
    line = refused(["verify-print", str(image)], str(image), f"{shape[1]} x {shape[0]} pixels",
                   "too small, no template marks fit in it", "at least 32 pixels")
    assert "cv2" not in line


def test_detecting_marks_in_a_degenerate_array_finds_none():
    import numpy as np

    from rgmcad.printing.marks import detect_marks

    for shape in [(0, 5), (1, 1), (1, 20000), (20000, 1), (33, 6000), (6000, 33)]:
        assert detect_marks(np.zeros(shape, np.uint8)) == {}


def test_a_mark_on_a_canvas_of_odd_shape_is_read_or_refused_in_one_line(tmp_path):
    import cv2
    import numpy as np
    from PIL import Image

    rng = random.Random(4)
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    for n in range(CASES):
        h, w = rng.choice([32, 40, 64, 200]), rng.choice([33, 900, 3000, 12000])
        h, w = (h, w) if rng.random() < 0.5 else (w, h)
        canvas = np.full((h, w), rng.choice([255, 200, 0]), np.uint8)
        side = max(10, int(min(h, w) * rng.uniform(0.3, 1.0)))
        mark = cv2.aruco.generateImageMarker(dictionary, rng.choice([4, 5, 6, 7, 0]), side)
        y, x = rng.randrange(0, h - side + 1), rng.randrange(0, w - side + 1)
        canvas[y:y + side, x:x + side] = mark
        image = tmp_path / f"mark-{n}.png"
        Image.fromarray(canvas).save(image, dpi=(rng.choice([1, 72, 600, 100_000]),) * 2)
        code, out, err = cli_output(["verify-print", str(image)])
        assert "Traceback" not in err and len(err.strip().splitlines()) <= 1, err
        assert code in (1, 2) and (code == 1 or str(image) in err), (code, out, err)


# --- 3. --parts DIR with a file that cannot be imported ------------------------------------------

_SYNTAX = ["def (:", "x = = 1", "))", "class", "return 5", '"""never closed', "if True:\nx = 1",
           "  indented = 1", "lambda: (yield)", "f'{'", "import", "x = [1, 2", "\x00",
           "def f():\n\treturn 1\n        return 2", "from __future__ import braces"]
_RAISES = ["1 / 0", "raise KeyError('k')", "raise SystemExit(3)", "raise SystemExit('bye')",
           "import no_such_module_here", "assert False, 'no'", "exit()",
           "raise type('Boom', (BaseException,), {})()", "def f(): return f()\nf()",
           "open('/no/such/file')", "int('x')", "[][1]", "raise GeneratorExit",
           "import sys; sys.exit(0)", "raise RuntimeError('line\\nbreak')"]


def _top_level_lines(text: str) -> list[int]:
    """0-based lines before which a statement can go: each top-level def or class, not
    split from its decorator, and the end."""
    lines = text.splitlines()
    spots = [i for i, line in enumerate(lines)
             if (line.startswith(("def ", "class ", "@", "FAMILY")) and
                 not (i and lines[i - 1].startswith("@")))]
    return spots + [len(lines)]


def _hostile_part_files(seed: int, tmp_path):
    """(folder, file, line or None, kind) of a copy of the shipped parts with one file
    damaged: a syntax error or a statement that raises, at a top-level spot."""
    import shutil

    from rgmcad.parts.family import DEFAULT_PARTS_DIR

    rng = random.Random(seed)
    folder = tmp_path / f"parts-{seed}"
    shutil.copytree(DEFAULT_PARTS_DIR, folder, ignore=shutil.ignore_patterns("__pycache__"))
    victim = rng.choice(sorted(p for p in folder.glob("*.py") if not p.name.startswith("_")))
    text = victim.read_text()
    kind = "syntax" if seed % 2 else "raises"
    insert = rng.choice(_SYNTAX if kind == "syntax" else _RAISES)
    at = rng.choice(_top_level_lines(text))
    lines = text.splitlines()
    victim.write_text("\n".join([*lines[:at], insert, *lines[at:]]) + "\n")
    return folder, victim, at + 1, kind


@pytest.mark.parametrize("seed", range(2 * CASES))
def test_a_part_file_that_cannot_be_imported_is_one_line_naming_it(seed, tmp_path):
    folder, victim, line, kind = _hostile_part_files(seed, tmp_path)
    said = refused(["check", "simple", "--parts", str(folder)], str(victim))
    assert "importing this part family file failed" in said
    if kind == "raises":  # the line of the statement that raised (a syntax error may be later)
        assert f"{victim}:{line}:" in said, said


def test_a_part_file_that_raises_keyboardinterrupt_is_an_interruption(tmp_path):
    folder, victim, _, _ = _hostile_part_files(0, tmp_path)
    victim.write_text("raise KeyboardInterrupt\n")
    code, _, err = cli_output(["check", "simple", "--parts", str(folder)])
    assert code == 130 and err.strip() == "rgmcad: interrupted"


# --- 4. a damaged part cache -----------------------------------------------------------------------


def _simple_cache(folder):
    """A part cache of the parts of ``simple`` (copied from the tests' own); the id of its
    ball (a part with a mesh)."""
    import shutil

    from rgmcad.cli.paths import default_build_dir
    from rgmcad.parts.store import part_id
    from rgmcad.scene.bodies import load_parts
    from rgmcad.scene.loader import load_scenario
    from rgmcad.shipped import scenario_path

    scenario = load_scenario(scenario_path("simple"))
    load_parts(scenario, default_build_dir())  # built there once, if not yet
    ids = {o.name: part_id(scenario.family(o), o.params) for o in scenario.body_objects()}
    for pid in set(ids.values()):
        shutil.copytree(default_build_dir() / pid, folder / pid)
    return ids["ball"]


class _Payload:
    """A pickle that leaves a file behind if it is ever unpickled."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


def _damage(rng: random.Random, folder, marker) -> str:
    """Damage the part in ``folder`` one random way; the name of the file damaged."""
    import io
    import json

    import numpy as np

    mesh, record = folder / "mesh.npz", folder / "part.json"
    arrays = dict(np.load(mesh))
    kind = rng.choice(["zero", "random", "truncate", "flip", "pickle", "shape", "dtype",
                       "range", "nan", "missing", "npy", "json", "json-type", "json-id",
                       "json-files", "json-key"])
    if kind == "zero":
        mesh.write_bytes(b"")
    elif kind == "random":
        mesh.write_bytes(rng.randbytes(rng.randrange(1, 4096)))
    elif kind == "truncate":
        data = mesh.read_bytes()
        mesh.write_bytes(data[:rng.randrange(len(data))])
    elif kind == "flip":
        data = bytearray(mesh.read_bytes())
        for _ in range(rng.randrange(1, 8)):
            data[rng.randrange(len(data))] ^= 1 << rng.randrange(8)
        mesh.write_bytes(bytes(data))
    elif kind == "npy":
        buf = io.BytesIO()
        np.save(buf, arrays["vertices_"])
        mesh.write_bytes(buf.getvalue())
    else:
        if kind == "pickle":
            arrays["vertices_"] = np.array([_Payload(marker)] * 3, dtype=object)
        elif kind == "shape":
            arrays["vertices_"] = arrays["vertices_"][:, :2]
        elif kind == "dtype":
            arrays["faces_"] = arrays["faces_"].astype(float)
        elif kind == "range":
            arrays["faces_"] = arrays["faces_"] + len(arrays["vertices_"])
        elif kind == "nan":
            arrays["vertices_"] = arrays["vertices_"] * np.nan
        elif kind == "missing":
            del arrays["faces_"]
        if not kind.startswith("json"):
            np.savez(mesh, **arrays, allow_pickle=True) if kind == "pickle" else np.savez(mesh, **arrays)
            return "mesh.npz"
        data = json.loads(record.read_text())
        if kind == "json":
            record.write_text(record.read_text()[:rng.randrange(1, 200)])
        elif kind == "json-type":
            record.write_text(json.dumps([data]))
        elif kind == "json-id":
            data["id"] = "ball-000000000000"
            record.write_text(json.dumps(data))
        elif kind == "json-files":
            data["files"]["step"] = "../../../etc/passwd"
            record.write_text(json.dumps(data))
        else:
            del data[rng.choice(["bodies", "joints", "files", "infinite"])]
            record.write_text(json.dumps(data))
        return "part.json"
    return "mesh.npz"


def test_a_damaged_part_is_refused_naming_its_file_never_unpickled(tmp_path):
    import shutil

    import numpy as np

    from rgmcad.parts.store import DamagedPart, PartStore

    cache = tmp_path / "cache"
    pid = _simple_cache(cache)
    good = PartStore(cache).load(pid)
    marker = tmp_path / "unpickled"
    rng = random.Random(5)
    for n in range(CASES):
        folder = tmp_path / f"case-{n}" / pid
        shutil.copytree(cache / pid, folder)
        damaged = _damage(rng, folder, marker)
        try:
            part = PartStore(folder.parent).load(pid)
        except DamagedPart as exc:
            assert str(exc).startswith(f"{folder / damaged}: ") and "\n" not in str(exc)
        else:  # the damage missed what is read: the part as it was built
            assert np.array_equal(part.main.vertices, good.main.vertices)
            assert np.array_equal(part.main.faces, good.main.faces)
        assert not marker.exists()


def test_a_damaged_part_cache_is_built_again_and_the_run_is_the_same(tmp_path, caplog):
    import json

    cache = tmp_path / "cache"
    pid = _simple_cache(cache)
    code, before, _ = cli_output(["simulate", "simple", "--build-dir", str(cache), "--json"])
    assert code == 0
    (cache / pid / "mesh.npz").write_bytes(b"PK\x03\x04 not a zip any more")
    code, after, err = cli_output(["simulate", "simple", "--build-dir", str(cache), "--json"])
    assert code == 0 and "Traceback" not in err, err
    warned = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert len(warned) == 1 and warned[0].startswith(
        f"{cache / pid / 'mesh.npz'}: a damaged part cache entry"), warned
    before, after = json.loads(before), json.loads(after)
    assert {**before, "wall_time": 0} == {**after, "wall_time": 0}


# --- 5. a full disk -------------------------------------------------------------------------------


class _SmallDisk:
    """A folder on a disk of ``kib`` KiB: a real tmpfs where this process may mount one (as
    root in a container), else a simulated one (:func:`rgmcad.files.write_all`, through
    which rgmcad's journal and atomic writes go, fails with ENOSPC once ``kib`` KiB went
    to files in the folder; or when ``RGMCAD_TEST_SIMULATED_DISK`` is set). :meth:`grow`
    makes room, :meth:`close` unmounts."""

    def __init__(self, folder, kib: int, monkeypatch):
        import os
        import shutil
        import subprocess

        self.folder = folder
        folder.mkdir(parents=True)
        self.real = (os.geteuid() == 0 and shutil.which("mount") is not None
                     and not os.environ.get("RGMCAD_TEST_SIMULATED_DISK") and subprocess.run(
            ["mount", "-t", "tmpfs", "-o", f"size={kib}k,mode=755", "tmpfs", str(folder)],
            capture_output=True).returncode == 0)
        if not self.real:
            import rgmcad.files

            self.left, real_write = kib * 1024, rgmcad.files.write_all

            def write_all(fd, data):
                try:
                    inside = folder in Path(os.readlink(f"/proc/self/fd/{fd}")).parents
                except OSError:
                    inside = True
                if inside and self.left is not None and len(data) > self.left:
                    real_write(fd, bytes(data)[:self.left])
                    self.left = 0
                    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
                if inside and self.left is not None:
                    self.left -= len(data)
                real_write(fd, data)

            monkeypatch.setattr(rgmcad.files, "write_all", write_all)

    def grow(self):
        import subprocess

        if self.real:
            subprocess.run(["mount", "-o", "remount,size=64m", str(self.folder)], check=True)
        else:
            self.left = None

    def close(self):
        import subprocess

        if self.real:
            subprocess.run(["umount", str(self.folder)], check=True)


@pytest.fixture
def small_disk(tmp_path, monkeypatch):
    disks = []

    def make(kib: int, name: str = "disk") -> _SmallDisk:
        disks.append(_SmallDisk(tmp_path / name, kib, monkeypatch))
        return disks[-1]

    yield make
    for disk in disks:
        disk.close()


def _record(rng: random.Random):
    from rgmcad.runs.problem import SimRecord
    from rgmcad.sim.run import Outcome

    ok = rng.random() < 0.5
    return SimRecord(True, Outcome.SUCCESS if ok else Outcome.FAILURE,
                     {"a": (ok, rng.random()), "b": (None, None)}, rng.random())


def test_a_full_disk_stops_the_journal_in_one_line_and_the_run_resumes(small_disk):
    import json

    from rgmcad.errors import RunDirectoryError
    from rgmcad.runs.store import SIMULATIONS, RunStore, run_identity
    from tests._support import TINY

    identity = run_identity("s", "0" * 64, 0, TINY)
    rng = random.Random(6)
    for n in range(CASES):
        disk = small_disk(rng.choice([16, 20, 24, 32, 40]), f"disk-{n}")
        run = disk.folder / "run"
        stored = []
        with RunStore(run, identity, dimension=3, events=["a", "b"]) as store:
            with pytest.raises(RunDirectoryError) as caught:
                for _ in range(10_000):
                    x, record = [rng.random() for _ in range(3)], _record(rng)
                    store.append(x, record, sync=rng.random() < 0.3)
                    stored.append((x, record))
        message = str(caught.value)
        assert message.startswith(f"{run / SIMULATIONS}: cannot be written (No space left on "
                                  "device); free some space"), message
        data = (run / SIMULATIONS).read_bytes()
        assert data.endswith(b"\n") and len(data.splitlines()) == len(stored) > 0
        assert all(json.loads(line) for line in data.splitlines())
        disk.grow()
        with RunStore(run, identity, dimension=3, events=["a", "b"]) as store:
            assert store.n_lines == len(stored) and store.n_rejected == 0
            assert all(store.lookup(x) == record for x, record in stored)
            store.append([0.5] * 3, _record(rng))  # and it goes on


def test_a_full_disk_under_an_output_file_is_one_line_and_no_torn_file(small_disk):
    disk = small_disk(8)
    page = disk.folder / "replay.html"
    page.write_text("the old page\n")
    refused(["simulate", "simple", "--html", str(page)], f"{page}: cannot be written (No space "
            "left on device); free some space and run the same command again")
    assert page.read_text() == "the old page\n"  # whole, or the old one
    assert sorted(p.name for p in disk.folder.iterdir()) == ["replay.html"]  # no temporary left


# --- 6. empty values -------------------------------------------------------------------------------

_GIVEN = {"scenario": "simple", "image": "sheet.png", "scenarios": "simple", "--layout": "initial",
          "--out": "out.png"}


def _blank_value_cases() -> list[tuple[list[str], str]]:
    """Every value-taking argument of every command (read from the parser), each given a
    blank value drawn at random, the command's other required arguments given."""
    from rgmcad.cli import build_parser

    rng = random.Random(8)
    cases = []
    for name, sub in build_parser().commands.items():
        takes = [a for a in sub._actions if a.nargs != 0 and a.dest != "help"]
        for target in takes:
            flag = target.option_strings[-1] if target.option_strings else target.dest
            argv = name.split()
            for a in takes:
                key = a.option_strings[-1] if a.option_strings else a.dest
                value = rng.choice(["", " ", "\t", "  \n "]) if a is target else _GIVEN.get(key)
                if a is not target and not a.required:
                    continue
                argv += [key, value] if a.option_strings else [value]
            cases.append((argv, flag))
    return cases


@pytest.mark.parametrize(("argv", "flag"), _blank_value_cases(),
                         ids=lambda v: "-".join(v) if isinstance(v, list) else v)
def test_an_empty_value_of_any_argument_is_refused_naming_it(argv, flag):
    refused(argv, f"argument {flag}", within=2.0)


def test_an_empty_output_or_start_is_refused_and_nothing_is_written(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    refused(["simulate", "simple", "--html", ""], "--html", "expected FILE")
    refused(["optimize", "simple", "--budget", "small", "--start", ""], "--start",
            "expected LAYOUT")
    refused(["check", "simple", "--parts", ""], "--parts", "expected DIR")
    assert list(tmp_path.iterdir()) == []  # no page, no run directory
