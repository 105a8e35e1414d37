"""Outputs onto FIFOs, devices, symbolic links, folders and sockets (:mod:`kronsub.atomic`): a
regular file is replaced through a temporary file, a link's target is written and the link
kept, a FIFO or a device is written directly, anything else is refused naming the path."""
from __future__ import annotations

import errno
import os
import socket
import stat
import threading
from pathlib import Path

import pytest
from click.testing import CliRunner

from conftest import MODELS
from kronsub import atomic
from kronsub.cli import main

SYSTEM1 = MODELS / "hoffmann" / "system1.yaml"


def cli(*args):
    return CliRunner().invoke(main, [*map(str, args)])


class Reader:
    """Everything written into the FIFO ``path``, read by a thread."""

    def __init__(self, path: Path):
        self.data = b""
        self.thread = threading.Thread(target=self._read, args=(path,), daemon=True)
        self.thread.start()

    def _read(self, path):
        with open(path, "rb") as fh:
            self.data = fh.read()

    def text(self) -> str:
        self.thread.join(60)
        assert not self.thread.is_alive()
        return self.data.decode()


def _fifo(path: Path) -> Path:
    os.mkfifo(path)
    return path


def _is_fifo(path: Path) -> bool:
    return stat.S_ISFIFO(os.lstat(path).st_mode)


def test_derive_into_a_fifo_writes_it_and_keeps_it_a_fifo(tmp_path):
    expected = cli("derive", SYSTEM1).stdout
    fifo = _fifo(tmp_path / "eqs.md")
    reader = Reader(fifo)
    result = cli("derive", SYSTEM1, "--output", fifo)
    assert result.exit_code == 0, result.output
    assert reader.text() == expected
    assert _is_fifo(fifo) and sorted(p.name for p in tmp_path.iterdir()) == ["eqs.md"]


def test_simulate_into_a_fifo_streams_the_csv_and_puts_no_sidecar_beside_it(tmp_path):
    fifo = _fifo(tmp_path / "traj.csv")
    reader = Reader(fifo)
    result = cli("simulate", SYSTEM1, "--t", "0.1", "--output", fifo)
    assert result.exit_code == 0, result.output
    assert reader.text().splitlines()[0].startswith("t,theta,")
    assert _is_fifo(fifo) and sorted(p.name for p in tmp_path.iterdir()) == ["traj.csv"]


def test_a_symbolic_link_is_followed_and_kept(tmp_path):
    target = tmp_path / "real" / "eqs.md"
    target.parent.mkdir()
    target.write_text("old")
    target.chmod(0o640)
    link = tmp_path / "eqs.md"
    link.symlink_to(target)
    result = cli("derive", SYSTEM1, "--output", link)
    assert result.exit_code == 0, result.output
    assert link.is_symlink() and os.readlink(link) == str(target)
    assert target.read_text().startswith("# System I") and target.stat().st_mode & 0o777 == 0o640
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["eqs.md", "eqs.md", "real"]  # no temporary


def test_a_dangling_link_gets_its_target_created(tmp_path):
    link = tmp_path / "eqs.md"
    link.symlink_to(tmp_path / "made.md")
    assert cli("derive", SYSTEM1, "--output", link).exit_code == 0
    assert link.is_symlink() and (tmp_path / "made.md").read_text().startswith("# System I")


def test_a_link_to_a_fifo_writes_the_fifo(tmp_path):
    fifo = _fifo(tmp_path / "pipe")
    link = tmp_path / "eqs.md"
    link.symlink_to(fifo)
    reader = Reader(fifo)
    assert cli("derive", SYSTEM1, "--output", link).exit_code == 0
    assert reader.text().startswith("# System I")
    assert link.is_symlink() and _is_fifo(fifo)


def test_dev_null_discards_and_stays_a_character_device(monkeypatch):
    """Safe to run as root: no temporary file can be made and nothing can be renamed here, so
    a write that tried to replace /dev/null fails the test instead of replacing it."""
    def refused(*args, **kwargs):
        raise AssertionError("a temporary file or a rename for /dev/null")

    monkeypatch.setenv("KRONSUB_CACHE_DIR", "off")  # (the cache's own writes use both)
    monkeypatch.setattr(atomic.tempfile, "mkstemp", refused)
    monkeypatch.setattr(atomic.os, "replace", refused)
    before = os.stat("/dev/null")
    for args in (("derive", SYSTEM1, "-o", "/dev/null"), ("derive", SYSTEM1, "--format", "json", "-o", "/dev/null")):
        result = cli(*args)
        assert result.exit_code == 0, result.output
    after = os.stat("/dev/null")
    assert stat.S_ISCHR(after.st_mode) and (after.st_ino, after.st_rdev) == (before.st_ino, before.st_rdev)


@pytest.mark.parametrize("make, needle", [
    (lambda p: p.mkdir(), "is a folder, not a file"),
    (lambda p: socket.socket(socket.AF_UNIX).bind(str(p)), "is a socket"),
])
def test_a_folder_or_a_socket_is_refused_naming_the_path(tmp_path, make, needle):
    out = tmp_path / "thing"
    make(out)
    with pytest.raises(OSError) as caught:
        atomic.write_atomically(out, "x")
    assert caught.value.filename == str(out) and needle in caught.value.strerror
    assert not list(tmp_path.glob(".*"))


def test_a_socket_as_output_is_an_error_and_is_left_alone(tmp_path):
    sock = tmp_path / "eqs.md"
    socket.socket(socket.AF_UNIX).bind(str(sock))
    result = cli("derive", SYSTEM1, "--output", sock)
    assert result.exit_code == 1
    assert f"Error: {sock}: is a socket" in result.output and ".tmp" not in result.output
    assert stat.S_ISSOCK(os.lstat(sock).st_mode)


def test_a_sidecar_that_is_a_folder_names_the_users_path(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    Path("out.json").mkdir()
    result = cli("simulate", SYSTEM1, "--t", "0.1", "-o", "out.csv")
    assert result.exit_code == 1
    assert "Error: out.json: is a folder, not a file" in result.output and ".tmp" not in result.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.json"]  # refused before the run


def test_a_sidecar_that_becomes_a_folder_during_the_run_names_the_users_path(tmp_path):
    """Past the check before the run: the write itself names the path, not its temporary file."""
    meta = tmp_path / "out.json"
    meta.mkdir()
    with pytest.raises(IsADirectoryError) as caught:
        atomic.write_atomically(meta, "{}")
    assert caught.value.filename == str(meta)


def test_codegen_writes_through_a_link_in_its_folder(tmp_path):
    out = tmp_path / "build"
    out.mkdir()
    target = tmp_path / "elsewhere.c"
    target.write_text("old")
    (out / "model.c").symlink_to(target)
    result = cli("codegen", SYSTEM1, "--lang", "c", "--output", out, "--name", "model")
    assert result.exit_code == 0, result.output
    assert (out / "model.c").is_symlink() and "ks_rhs" in target.read_text()


def test_a_plot_onto_a_link_writes_its_target(tmp_path):
    pytest.importorskip("matplotlib")
    target = tmp_path / "real.png"
    link = tmp_path / "plot.png"
    link.symlink_to(target)
    result = cli("simulate", SYSTEM1, "--t", "0.1", "--plot", link, "-o", tmp_path / "t.csv")
    assert result.exit_code == 0, result.output
    assert link.is_symlink() and target.read_bytes()[:4] == b"\x89PNG"


def test_an_animation_into_a_fifo_and_through_a_link(tmp_path):
    pytest.importorskip("matplotlib")
    pytest.importorskip("PIL")
    fifo = _fifo(tmp_path / "motion.gif")
    reader = Reader(fifo)
    result = cli("animate", SYSTEM1, "--output", fifo, "--t", "0.2", "--dt", "0.1", "--fps", "10", "--size", "64")
    assert result.exit_code == 0, result.output
    reader.thread.join(60)
    assert reader.data[:6] == b"GIF89a" and _is_fifo(fifo)
    target = tmp_path / "real.gif"
    link = tmp_path / "link.gif"
    link.symlink_to(target)
    result = cli("animate", SYSTEM1, "--output", link, "--t", "0.2", "--dt", "0.1", "--fps", "10", "--size", "64")
    assert result.exit_code == 0, result.output
    assert link.is_symlink() and target.read_bytes()[:6] == b"GIF89a"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.gif", "motion.gif", "real.gif"]


def test_an_animation_on_a_full_disk_names_the_file(tmp_path, monkeypatch):
    pytest.importorskip("matplotlib")
    from PIL import Image

    def full(self, filename, *args, **kwargs):  # Pillow's GIF writer, part of the file written
        Path(filename).write_bytes(b"GIF")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(Image.Image, "save", full)
    out = tmp_path / "motion.gif"
    result = cli("animate", SYSTEM1, "--output", out, "--t", "0.2", "--dt", "0.1", "--fps", "10", "--size", "64")
    assert result.exit_code == 1
    assert f"Error: {out}: No space left on device" in result.output
    assert list(tmp_path.iterdir()) == []  # no temporary file left


def test_a_temporary_named_in_an_error_becomes_the_users_path(tmp_path, monkeypatch):
    """An OSError naming the temporary file (a rename, a writer that opens its own name) names
    the user's path instead."""
    out = tmp_path / "motion.gif"

    def fails(*args):
        raise OSError(errno.EIO, "Input/output error", args[0])

    with pytest.raises(OSError) as caught:
        with atomic.atomic_path(out) as tmp:
            fails(str(tmp))
    assert caught.value.filename == str(out) and list(tmp_path.iterdir()) == []


def test_a_file_in_a_folder_no_file_can_be_created_in_is_written_in_place(tmp_path, monkeypatch):
    out = tmp_path / "eqs.md"
    out.write_text("old")

    def no_room(*args, **kwargs):
        raise PermissionError(errno.EACCES, "Permission denied")

    monkeypatch.setattr(atomic.tempfile, "mkstemp", no_room)
    atomic.write_atomically(out, "new")
    assert out.read_text() == "new"
    with pytest.raises(PermissionError) as caught:  # a new file still needs the folder
        atomic.write_atomically(tmp_path / "other.md", "new")
    assert caught.value.filename == str(tmp_path / "other.md")


@pytest.mark.parametrize("name", ["/dev/stdout", "/dev/fd/1", "/proc/self/fd/1"])
def test_standard_output_redirected_to_a_file_is_written_in_place(tmp_path, name):
    """``-o /dev/stdout`` with standard output redirected to a file: the file the shell opened is
    written in place (a rename would replace /dev/stdout itself, or miss the shell's file). Only
    asked, in a child whose standard output is the file: nothing is written to /dev here."""
    import subprocess
    import sys

    out = tmp_path / "eqs.md"
    code = f"import sys; from kronsub import atomic; print(atomic.output_target({name!r}), file=sys.stderr)"
    with open(out, "w") as fh:
        proc = subprocess.run([sys.executable, "-c", code], stdout=fh, stderr=subprocess.PIPE, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.strip() == f"('stream', PosixPath({name!r}))"


def test_proc_fd_output_writes_the_shells_file(tmp_path):
    import subprocess
    import sys

    out = tmp_path / "eqs.md"
    with open(out, "w") as fh:
        proc = subprocess.run([sys.executable, "-m", "kronsub", "derive", str(SYSTEM1), "-o", "/proc/self/fd/1"],
                              stdout=fh, stderr=subprocess.PIPE, text=True, timeout=120,
                              env={**os.environ, "KRONSUB_CACHE_DIR": "off"})
    assert proc.returncode == 0, proc.stderr
    assert out.read_text().startswith("# System I") and sorted(p.name for p in tmp_path.iterdir()) == ["eqs.md"]


def test_temporary_names_include_the_suffix_a_writer_needs():
    assert atomic.temporary_pattern("m.gif").fullmatch(".m.gif.abcdefgh.tmp.gif")
    assert atomic.temporary_pattern("m.gif").fullmatch(".m.gif.abcdefgh.tmp")
    assert not atomic.temporary_pattern("m.gif").fullmatch(".m.gif.abcdefgh.tmp.bak")


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full")
def test_a_full_device_names_the_path_the_user_gave(tmp_path, monkeypatch):
    """/dev/full (every write: ENOSPC), directly and through a link named like an animation.
    Nothing may be renamed here (a regression fails the test instead of replacing /dev/full)."""
    real = os.replace

    def guarded(src, dst, *args, **kwargs):
        if str(dst).startswith("/dev/"):
            raise AssertionError(f"a rename onto {dst}")
        return real(src, dst, *args, **kwargs)

    monkeypatch.setenv("KRONSUB_CACHE_DIR", "off")
    monkeypatch.setattr(atomic.os, "replace", guarded)
    result = cli("derive", SYSTEM1, "-o", "/dev/full")
    assert result.exit_code == 1
    assert "Error: /dev/full: No space left on device" in result.output
    pytest.importorskip("matplotlib")
    pytest.importorskip("PIL")
    link = tmp_path / "motion.gif"
    link.symlink_to("/dev/full")
    result = cli("animate", SYSTEM1, "--output", link, "--t", "0.2", "--dt", "0.1", "--fps", "10", "--size", "64")
    assert result.exit_code == 1
    assert f"Error: {link}: No space left on device" in result.output
    assert stat.S_ISCHR(os.stat("/dev/full").st_mode) and link.is_symlink()


@pytest.mark.parametrize("stem", ["b" * 250, "é" * 124, "x" * 251])
def test_a_name_as_long_as_the_file_system_allows_is_written(tmp_path, stem):
    """The temporary file beside a target of a long name (up to NAME_MAX bytes) gets a shortened
    name of its own that fits, still recognised as the target's (a stale one is cleaned)."""
    import os
    import time

    from kronsub.atomic import (NAME_MAX, STALE_AFTER, atomic_path, clean_stale, temporary_pattern, temporary_stem,
                                write_atomically)

    target = tmp_path / f"{stem}.csv"
    assert len(os.fsencode(target.name)) <= NAME_MAX
    write_atomically(target, "t\n0\n")
    assert target.read_text() == "t\n0\n" and os.listdir(tmp_path) == [target.name]
    with atomic_path(target) as tmp:  # a writer that wants the suffix
        assert tmp.suffix == ".csv" and len(os.fsencode(tmp.name)) <= NAME_MAX
        assert temporary_pattern(target.name).fullmatch(tmp.name)
        tmp.write_text("t\n1\n")
    assert target.read_text() == "t\n1\n" and os.listdir(tmp_path) == [target.name]
    left = tmp_path / f".{temporary_stem(target.name)}.abcd_123.tmp"  # left by a killed write
    left.write_text("t\n")
    os.utime(left, (time.time() - 2 * STALE_AFTER,) * 2)
    assert len(os.fsencode(left.name)) <= NAME_MAX and clean_stale(target) == [left]
