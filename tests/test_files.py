"""Files written whole or not at all (run stores, manifests, layouts, reports)."""

import json
import os

import pytest

from rgmcad.files import write_atomic, write_json_atomic


def test_a_write_that_dies_midway_leaves_the_old_file_and_no_debris(tmp_path, monkeypatch):
    path = tmp_path / "layout.json"
    write_json_atomic(path, {"x": 1})

    def power_cut(fd):
        raise OSError("power cut")

    monkeypatch.setattr(os, "fsync", power_cut)
    with pytest.raises(OSError, match="power cut"):
        write_json_atomic(path, {"x": 2, "long": "y" * 100_000})
    assert json.loads(path.read_text()) == {"x": 1}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["layout.json"]


def test_text_and_bytes_round_trip(tmp_path):
    assert write_atomic(tmp_path / "a.md", "é\n").read_text(encoding="utf-8") == "é\n"
    assert write_atomic(tmp_path / "b.bin", b"\x00\x01").read_bytes() == b"\x00\x01"


def test_files_written_are_as_readable_as_any_other_file_of_the_user(tmp_path):
    # a run folder shared with a class or served by a web server: layout.json, result.json
    # and report.md must be readable like the PNGs beside them (mkstemp alone makes 0600)
    ordinary = tmp_path / "plot.png"
    ordinary.write_bytes(b"png")
    written = write_json_atomic(tmp_path / "layout.json", {"x": 1})
    assert written.stat().st_mode & 0o777 == ordinary.stat().st_mode & 0o777
    os.chmod(written, 0o640)  # a mode the user chose is kept when the file is rewritten
    write_json_atomic(written, {"x": 2})
    assert written.stat().st_mode & 0o777 == 0o640
