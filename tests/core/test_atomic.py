"""Atomic writes: complete or absent, and files with the permissions a user expects."""

import os
import stat

import pytest

from dynid.atomic import write_atomic


def test_new_files_follow_the_umask_and_replaced_files_keep_their_mode(tmp_path):
    old = os.umask(0o022)
    try:
        p = write_atomic(tmp_path / "a.txt", "x")
        assert stat.S_IMODE(p.stat().st_mode) == 0o644  # not the 0600 of a temporary file
        os.chmod(p, 0o600)
        write_atomic(p, "y")
        assert stat.S_IMODE(p.stat().st_mode) == 0o600 and p.read_text() == "y"
    finally:
        os.umask(old)


def test_a_failed_write_leaves_the_old_file_and_no_temporary(tmp_path, monkeypatch):
    p = write_atomic(tmp_path / "a.txt", "old")
    monkeypatch.setattr(os, "replace", lambda *a: (_ for _ in ()).throw(OSError("rename failed")))
    with pytest.raises(OSError, match="rename failed"):
        write_atomic(p, "new")
    assert p.read_text() == "old" and os.listdir(tmp_path) == ["a.txt"]
