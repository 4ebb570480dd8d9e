"""The command line on bad input, as a law: for every command of ``rgmcad.cli.COMMANDS``, a
bad argument vector (unknown flag, missing argument, wrong type, negative, zero, huge, NaN or
infinite number, missing file, folder, garbage file as scenario, layout or image, an output
that cannot be written) either succeeds or exits with status 2 and exactly one line on stderr,
``rgmcad: error: ...``, never a traceback, a usage text or a native abort.

Vectors marked with a word must fail, and their line must hold that word (the flag, or what
is allowed). The slow commands (optimize, evaluate) only get vectors refused before any work.
"""

from __future__ import annotations

import io
import json
import os
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from PIL import Image

from rgmcad.cli import COMMANDS, main

ROOT = Path(__file__).resolve().parent.parent
BUILD = str(ROOT / "build" / "parts")


# --- garbage on disk -----------------------------------------------------------------------------

def _png_header(width: int, height: int, colour: int = 0) -> bytes:
    """A PNG that claims ``width x height`` pixels but holds a few rows (a decompression bomb's
    header: a reader that decodes before checking the size allocates for all of them)."""
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    ihdr = struct.pack(">IIBBBBB", width, height, 8, colour, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr)
            + chunk(b"IDAT", zlib.compress(b"\0" * 64)) + chunk(b"IEND", b""))


def _patched(fmt: str, offset_of, pack: str, size=(40000, 40000)) -> bytes:
    """A tiny image of format ``fmt`` whose header is rewritten to claim ``size``."""
    buf = io.BytesIO()
    Image.new("L", (8, 8)).save(buf, fmt)
    data = bytearray(buf.getvalue())
    struct.pack_into(pack, data, offset_of(data), *size)
    return bytes(data)


@pytest.fixture(scope="module")
def f(tmp_path_factory):
    """Paths of garbage: files, folders and outputs that cannot be written."""
    tmp = tmp_path_factory.mktemp("fuzz")
    files = {
        "empty": b"", "binary": bytes(range(256)) * 4, "toml_garbage": b"name = [\n",
        "json_list": b"[1, 2, 3]", "text": b"hello\n",
        "nan_layout": b'{"scenario": "simple", "vector": [NaN, 0.5, 0.5]}',
        "bomb.png": _png_header(40000, 40000),
        "bomb_rgba.png": _png_header(12000, 12000, colour=6),  # past PIL's warning only
        "just_over.png": _png_header(9000, 9000),  # past our limit, under PIL's warning
        "bomb.jpg": _patched("JPEG", lambda d: d.index(b"\xff\xc0") + 5, ">HH"),
        "bomb.bmp": _patched("BMP", lambda d: 18, "<ii"),
        "bomb.gif": _patched("GIF", lambda d: 6, "<HH"),
        "text.png": b"not a picture\n",
    }
    paths = {}
    for name, data in files.items():
        paths[name] = tmp / name
        paths[name].write_bytes(data)
    buf = io.BytesIO()
    Image.new("RGB", (64, 48), (200, 10, 10)).save(buf, "PNG")
    paths["truncated.png"] = tmp / "truncated.png"
    paths["truncated.png"].write_bytes(buf.getvalue()[:60])
    Image.new("L", (1, 1)).save(tmp / "tiny.png")
    paths["tiny.png"] = tmp / "tiny.png"
    paths["dir"] = tmp / "folder"
    paths["dir"].mkdir()
    paths["file"] = tmp / "a_file"
    paths["file"].write_text("x")
    paths["missing"] = tmp / "missing.toml"
    paths["no_parent"] = tmp / "no" / "such" / "out.png"
    paths["under_file"] = paths["file"] / "out.png"
    (tmp / "writes_into" / "template.pdf").mkdir(parents=True)
    (tmp / "writes_into" / "manifest.json").mkdir()
    paths["occupied"] = tmp / "writes_into"
    paths["run"] = tmp / "run"
    paths["ok_png"] = tmp / "ok.png"
    if hasattr(os, "mkfifo"):
        paths["fifo"] = tmp / "fifo"
        os.mkfifo(paths["fifo"])
    # the part cache of simple, built before (a first build says so on stderr)
    assert main(["--build-dir", BUILD, "check", "simple"]) == 0
    return {k: str(v) for k, v in paths.items()}


# --- the vectors ---------------------------------------------------------------------------------

BAD_SCENARIOS = ("missing", "dir", "empty", "binary", "toml_garbage", "json_list", "tiny.png",
                 "fifo")
BAD_NUMBERS = ("-5", "0", "-0", "1e3", "abc", "nan", "inf", "-inf", "", "0x10", "99999999999999")


def _vectors(f) -> list[tuple[str, list[str], str | None]]:
    """(kind, argv, a word the error line must hold, or None: may succeed)."""
    v = []
    scen = [f[k] for k in BAD_SCENARIOS if k in f] + ["", "no_such_shipped_scenario"]
    out_png = f["ok_png"]
    # every command: unknown flag, missing argument, garbage scenario
    for cmd in COMMANDS:
        words = cmd.split()
        extra = {"render": ["--out", out_png], "template": ["--out", f["run"] + "_tpl"],
                 "optimize": ["--run", f["run"], "--budget", "small"],
                 "evaluate": ["--layout", "initial", "--rho-g", "--samples", "1"],
                 "build parts": ["--out", f["run"] + "_parts"],
                 "export": ["--out", f["run"] + ".step"],
                 "supports": ["--out", f["run"] + "_supports"]}.get(cmd, [])
        first = f["tiny.png"] if cmd == "verify-print" else "simple"
        for flag in ("--no-such-flag", "--no-such-flag=3", "-Z"):
            v.append(("unknown flag", [*words, first, *extra, flag], flag.split("=")[0]))
        v.append(("missing argument", [*words, "--json"] if cmd != "build parts"
                  else [*words, "--out"], "--out" if cmd == "build parts" else "required"))
        if cmd == "verify-print":
            continue
        for s in scen:
            v.append(("garbage scenario", [*words, s, *extra], None))
    # global flags and commands
    v += [("missing argument", [], "COMMAND"), ("unknown command", ["no-such-command"], "invalid"),
          ("unknown flag", ["--no-such-flag", "check", "simple"], "--no-such-flag"),
          ("missing argument", ["build"], "WHAT"),
          ("unknown command", ["build", "everything"], "invalid"),
          ("missing argument", ["--build-dir"], "--build-dir"),
          ("bad output", ["--build-dir", f["file"], "check", "simple"], "--build-dir"),
          ("bad output", ["--build-dir", f["under_file"], "simulate", "simple"], "--build-dir"),
          ("bad output", ["--build-dir", "", "check", "simple"], "--build-dir"),
          ("bad output", ["--build-dir", f["file"], "build", "parts"], "--build-dir")]
    # numbers: pixels, vectors, overlap, seeds, workers, samples
    for flag in ("--width", "--height"):
        for n in (*BAD_NUMBERS, "15", "8193", "40000"):
            v.append(("bad number", ["render", "simple", "--out", out_png, flag, n], flag))
        for n in (*BAD_NUMBERS, "15", "4097", "40000"):
            v.append(("bad number", ["simulate", "simple", flag, n], flag))
            v.append(("bad number", ["simulate", "simple", "--video", f["run"] + ".gif", flag, n],
                      flag))
    v.append(("bad number", ["simulate", "simple", "--video", f["run"] + ".gif", "--width",
                             "4096", "--height", "4096"], "--width/--height"))
    for vec in ("nan,nan,nan", "inf,0.5,0.5", "", "a,b,c", "1e309,0.5,0.5", "0.5", "0.5,,0.5",
                "-0.1,0.5,0.5", "0.5," * 999 + "0.5"):
        v.append(("bad vector", ["simulate", "simple", "--vector", vec, "--json"], None))
        v.append(("bad vector", ["render", "simple", "--out", out_png, "--vector", vec,
                                 "--width", "16", "--height", "16"], None))
    v.append(("exclusive flags", ["simulate", "simple", "--layout", "solved", "--vector",
                                  "0.5,0.5,0.5"], "not allowed"))
    for n in ("nan", "inf", "-inf", "abc", ""):
        v.append(("bad number", ["template", "simple", "--out", f["run"] + "_t", "--overlap", n],
                  "--overlap"))
    for n in ("-1", "1e9"):
        v.append(("bad number", ["template", "simple", "--out", f["run"] + "_t", "--overlap", n],
                  "overlap"))
    v += [("bad choice", ["template", "simple", "--out", f["run"] + "_t", "--paper", "b5"],
           "--paper"),
          ("bad choice", ["template", "simple", "--out", f["run"] + "_t", "--plane", "up"],
           "--plane"),
          ("bad choice", ["optimize", "simple", "--budget", "huge"], "--budget"),
          ("flag of another command", ["template", "simple", "--out", f["run"] + "_t",
                                       "--vector", "0.5,0.5,0.5"], "--vector"),
          ("flag value", ["build", "parts", "--force=1"], "--force")]
    for flag in ("--seed", "--workers"):
        for n in ("abc", "nan", "1.5", ""):
            v.append(("bad number", ["optimize", "simple", "--run", f["run"], flag, n], flag))
            v.append(("bad number", ["evaluate", "simple", "--layout", "initial", flag, n], flag))
    for n in ("abc", "0", "-1", ""):
        v.append(("bad number", ["evaluate", "simple", "--layout", "initial", "--rho-g",
                                 "--samples", n], "--samples"))
    # layouts
    for key in ("missing", "dir", "empty", "binary", "json_list", "toml_garbage", "fifo",
                "nan_layout"):
        if key in f:
            for cmd in (["simulate", "simple"], ["render", "simple", "--out", out_png],
                        ["template", "simple", "--out", f["run"] + "_t"],
                        ["evaluate", "simple", "--rho-g", "--samples", "1"]):
                if cmd[0] != "evaluate" or key != "nan_layout":  # evaluate must not run
                    v.append(("garbage layout", [*cmd, "--layout", f[key]], None))
    # outputs
    for key, word in (("no_parent", "does not exist"), ("under_file", "is a file"),
                      ("dir", "is a folder")):
        v.append(("bad output", ["render", "simple", "--out", f[key]], word))
        v.append(("bad output", ["simulate", "simple", "--video", f[key][:-4] + ".gif"
                                 if key != "dir" else f[key]], word))
    for name in ("x.jpg", "x.avi", "x", "x.png.txt"):
        target = str(Path(f["run"]).parent / name)
        if name != "x.avi":
            v.append(("bad output", ["render", "simple", "--out", target], "extension"))
        if name != "x.jpg":
            v.append(("bad output", ["simulate", "simple", "--video", target], "extension"))
    for flag_cmd in (["template", "simple"], ["build", "parts", "simple"]):
        for key, word in (("file", "is a file"), ("under_file", "is a file"),
                          ("occupied", "is a folder where")):
            v.append(("bad output", [*flag_cmd, "--out", f[key]], word))
        v.append(("bad output", [*flag_cmd, "--out", ""], "--out"))
    v.append(("bad output", ["render", "simple", "--out", ""], "--out"))
    # images
    for key in ("missing", "dir", "empty", "binary", "text.png", "truncated.png", "fifo"):
        if key in f:
            v.append(("garbage image", ["verify-print", f[key]], f[key]))
            v.append(("garbage image", ["verify-print", f[key], "--json"], f[key]))
    for key in ("bomb.png", "bomb_rgba.png", "just_over.png", "bomb.jpg", "bomb.bmp",
                "bomb.gif"):
        v.append(("decompression bomb", ["verify-print", f[key]], "million pixels"))
    v.append(("garbage image", ["verify-print", f["tiny.png"]], "no template marks"))
    v.append(("garbage image", ["verify-print", ""], None))
    return v


def _run(argv, capfd) -> tuple[int, str, str]:
    rc = main(["--build-dir", BUILD, *argv] if argv[:1] != ["--build-dir"] and argv else argv)
    out, err = capfd.readouterr()
    return rc, out, err


def _obeys(argv, rc, out, err, word):
    shown = f"{argv}: rc {rc}, stderr {err!r}"
    assert "Traceback" not in err and "usage:" not in err, shown
    if word is not None:
        assert rc == 2, shown
    # 1: a layout that fails or is invalid (simulate), or a named one that is (check)
    assert rc in (0, 2) or rc == 1 and {"simulate", "check"} & set(argv), shown
    if rc == 2:
        lines = err.splitlines()
        assert len(lines) == 1 and lines[0].startswith("rgmcad: error: "), shown
        if word is not None:
            assert word in lines[0], shown
        if "--json" in argv:
            assert out == "", shown


def test_every_bad_vector_gives_success_or_one_line_and_status_2(f, capfd):
    vectors = _vectors(f)
    kinds: dict[str, int] = {}
    for kind, argv, word in vectors:
        kinds[kind] = kinds.get(kind, 0) + 1
        rc, out, err = _run(argv, capfd)
        _obeys(argv, rc, out, err, word)
    assert len(vectors) > 300 and len(kinds) >= 10, kinds
    assert {argv[0] if argv[0] != "build" else "build parts" for _, argv, _ in vectors
            if argv and not argv[0].startswith("-")} >= set(COMMANDS)


@pytest.mark.parametrize("argv, flag", [
    (["simulate", "simple", "--video", "{tmp}/x.avi"], "--video"),
    (["simulate", "simple", "--video", "{file}/x.mp4"], "--video"),
    (["simulate", "simple", "--video", "{tmp}/x.gif", "--width", "4096", "--height", "4096"],
     "--width/--height"),
    (["render", "simple", "--out", "{tmp}/no/x.png"], "--out"),
    (["render", "simple", "--out", "{tmp}/x.jpg"], "--out"),
    (["template", "simple", "--out", "{file}"], "--out"),
    (["build", "parts", "simple", "--out", "{file}/parts"], "--out"),
])
def test_output_problems_are_found_before_any_part_is_built(argv, flag, f, tmp_path, capfd):
    cache = tmp_path / "cache"  # a fresh part cache: any work would build into it first
    argv = [a.format(tmp=tmp_path, file=f["file"]) for a in argv]
    assert main(["--build-dir", str(cache), *argv]) == 2
    err = capfd.readouterr().err
    assert len(err.splitlines()) == 1 and f"{flag}:" in err, err
    assert not cache.exists()


def test_a_nul_in_a_path_is_one_line(f, capfd):
    # only in-process: a command line cannot hold a NUL
    for argv in (["render", "simple", "--out", "a\0.png"], ["simulate", "a\0.toml"],
                 ["template", "simple", "--out", "a\0b"], ["verify-print", "a\0.png"]):
        rc, out, err = _run(argv, capfd)
        _obeys(argv, rc, out, err, "rgmcad: error: ")


def test_help_still_prints_help_and_exits_0(capfd):
    for argv in (["--help"], ["simulate", "--help"], ["build", "parts", "--help"]):
        assert main(argv) == 0
        out, err = capfd.readouterr()
        assert out.startswith("usage: rgmcad") and err == ""


TOKENS = st.sampled_from(["--width", "--height", "--vector", "--layout", "--out", "--json",
                          "--video", "--paper", "-5", "0", "nan", "inf", "1e9", "abc", "",
                          "0.5,0.5,0.5", "solved", "x.jpg", "x.avi", "--", "-", "simple"])
JUNK = st.text(alphabet="-abcz019,: ", max_size=8)


@settings(max_examples=200, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(command=st.sampled_from(["simulate", "render", "check", "verify-print"]),
       rest=st.lists(st.one_of(TOKENS, JUNK), max_size=6))
def test_random_argument_vectors_obey_the_law(command, rest, capfd, tmp_path_factory):
    # outputs are relative names without a folder: they would land in the current folder
    cwd = os.getcwd()
    os.chdir(tmp_path_factory.getbasetemp())
    try:
        rc, out, err = _run([command, *rest], capfd)
    finally:
        os.chdir(cwd)
    _obeys([command, *rest], rc, out, err, None)


# --- a real process ------------------------------------------------------------------------------

def _cli(*argv, limit_memory: bool = False):
    def limit():  # 1 GiB of address space: a decoded 40 000 x 40 000 image cannot fit
        import resource

        resource.setrlimit(resource.RLIMIT_AS, (2**30, 2**30))

    return subprocess.run([sys.executable, "-m", "rgmcad.cli", "--build-dir", BUILD, *argv],
                          capture_output=True, text=True, cwd=ROOT, timeout=120,
                          preexec_fn=limit if limit_memory and sys.platform == "linux" else None)


@pytest.mark.parametrize("argv, word", [
    (["render", "simple", "--out", "{tmp}/x.png", "--width", "-5"], "--width"),  # native abort
    (["render", "simple", "--out", "{tmp}/x.png", "--height", "40000"], "--height"),
    (["simulate", "simple", "--video", "{tmp}/x.avi"], "--video"),
    (["simulate", "simple", "--no-such-flag"], "--no-such-flag"),
    (["template", "simple", "--out", "{tmp}/t", "--paper"], "--paper"),
    (["verify-print", "{bomb}"], "million pixels"),
])
def test_one_line_and_status_2_from_a_real_process(argv, word, f, tmp_path):
    argv = [a.format(tmp=tmp_path, bomb=f["bomb_rgba.png"]) for a in argv]
    done = _cli(*argv, limit_memory=argv[0] == "verify-print")
    assert done.returncode == 2, done.stderr
    assert done.stdout == ""
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("rgmcad: error: ") and word in lines[0], lines


def test_json_output_is_exactly_one_line_and_nothing_else():
    # pybullet prints a banner from C when imported: it must reach neither stream
    done = _cli("simulate", "simple", "--json")
    assert done.returncode == 0, done.stderr
    assert done.stderr == ""
    lines = done.stdout.splitlines()
    assert len(lines) == 1 and json.loads(lines[0])["outcome"] == "success"
