"""Atomic writes and output-folder checks: whole files or none, and one line naming the path."""

import errno
import os

import pytest

from kgn_bench.errors import KGNBenchError, OutputError
from kgn_bench.io import atomic_write_text, check_writable_dir, describe_os_error

READ_ONLY = "/sys"  # sysfs refuses new files even to root (chmod does not stop root)


def test_atomic_write_leaves_no_temporary_files(tmp_path):
    atomic_write_text(tmp_path / "a.txt", "hello")
    assert (tmp_path / "a.txt").read_text() == "hello"
    assert [p.name for p in tmp_path.iterdir()] == ["a.txt"]
    assert (tmp_path / "a.txt").stat().st_mode & 0o777 == 0o644  # readable like a plain open(), not mkstemp's 0600


def test_a_full_disk_keeps_the_old_file_and_names_the_path(tmp_path, monkeypatch):
    target = tmp_path / "summary.json"
    target.write_text("old")

    def full(fd):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "fsync", full)
    with pytest.raises(OutputError) as e:
        atomic_write_text(target, "new")
    assert str(e.value) == f"cannot write {target}: disk full"
    assert isinstance(e.value, KGNBenchError)
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["summary.json"]


def test_atomic_write_into_a_read_only_folder_is_one_line():
    with pytest.raises(OutputError, match=r"^cannot write /sys/kgn\.json: "):
        atomic_write_text(f"{READ_ONLY}/kgn.json", "x")


def test_check_writable_dir_checks_without_writing(tmp_path):
    check_writable_dir(tmp_path / "a" / "b")
    assert list(tmp_path.iterdir()) == []  # nothing created, the probe file is gone
    (tmp_path / "file").write_text("x")
    with pytest.raises(OutputError, match="is a file, not a folder"):
        check_writable_dir(tmp_path / "file", "run folder")
    with pytest.raises(OutputError, match="is a file, not a folder"):
        check_writable_dir(tmp_path / "file" / "sub")
    with pytest.raises(OutputError, match="is a file, not a folder"):
        check_writable_dir(tmp_path / "file" / "sub")
    with pytest.raises(OutputError, match=r"^output folder /sys is not writable"):
        check_writable_dir(READ_ONLY)
    with pytest.raises(OutputError, match=r"not writable"):
        check_writable_dir(f"{READ_ONLY}/kgn_bench_out")


def test_describe_os_error():
    assert describe_os_error(OSError(errno.ENOSPC, "x", "f.txt")) == "cannot write f.txt: disk full"
    assert describe_os_error(OSError(errno.EACCES, "Permission denied", "g")) == "cannot write g: Permission denied"


def test_a_stop_signal_during_a_write_takes_effect_after_it(tmp_path):
    """SIGTERM sent in the middle of a write: the file is written whole, then the stop is raised."""
    import signal

    from kgn_bench.io import atomic_write
    from kgn_bench.lifecycle import Stopped, interrupts_as_keyboard

    def write(f):
        f.write(b"first half ")
        os.kill(os.getpid(), signal.SIGTERM)
        for _ in range(1000):  # bytecode boundaries at which an undeferred handler would have raised
            pass
        f.write(b"second half")

    target = tmp_path / "record.json"
    with pytest.raises(Stopped), interrupts_as_keyboard():
        atomic_write(target, write)
    assert target.read_bytes() == b"first half second half"
    assert [p.name for p in tmp_path.iterdir()] == ["record.json"]
