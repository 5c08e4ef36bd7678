"""The one atomic write (reports, plans): whole files, clear errors naming the path."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import numpy as np
import pytest

from optik.errors import OptikError, OutputFileError
from optik.planning import plan_path
from optik.problems import load_problem
from optik.report import write_atomic


def _leftovers(folder: Path) -> list[Path]:
    return [p for p in folder.rglob("*") if p.name.startswith(".")]


def test_write_atomic_writes_text_and_bytes_whole(tmp_path: Path) -> None:
    text = write_atomic(tmp_path / "sub" / "a.txt", "é\nline\n")
    data = write_atomic(tmp_path / "b.bin", b"\x00\x01\xff")
    assert text.read_bytes() == "é\nline\n".encode()
    assert data.read_bytes() == b"\x00\x01\xff"
    write_atomic(text, "new")
    assert text.read_text(encoding="utf-8") == "new"
    assert not _leftovers(tmp_path)


def test_write_atomic_gives_the_permissions_of_a_plain_write(tmp_path: Path) -> None:
    plain = tmp_path / "plain.txt"
    with open(plain, "w", encoding="utf-8") as f:  # the reference: what open() creates
        f.write("x")
    new = write_atomic(tmp_path / "new.txt", "x")
    assert stat.S_IMODE(new.stat().st_mode) == stat.S_IMODE(plain.stat().st_mode)
    os.chmod(new, 0o640)
    write_atomic(new, "replaced")
    assert stat.S_IMODE(new.stat().st_mode) == 0o640  # a replaced file keeps its mode


def test_write_atomic_syncs_before_the_rename(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    order: list[str] = []
    real_fsync, real_replace = os.fsync, os.replace
    monkeypatch.setattr(os, "fsync", lambda fd: (order.append("fsync"), real_fsync(fd))[1])
    monkeypatch.setattr(
        os, "replace", lambda a, b: (order.append("replace"), real_replace(a, b))[1]
    )
    write_atomic(tmp_path / "a.txt", "x")
    assert order == ["fsync", "replace"]


def test_a_folder_in_place_of_the_file_is_named(tmp_path: Path) -> None:
    (tmp_path / "taken").mkdir()
    with pytest.raises(OutputFileError, match=r"taken.*is a folder") as info:
        write_atomic(tmp_path / "taken", "x")
    assert info.value.path == str(tmp_path / "taken")
    assert isinstance(info.value, OptikError)


def test_a_file_in_place_of_the_folder_is_named(tmp_path: Path) -> None:
    (tmp_path / "plain").write_text("not a folder", encoding="utf-8")
    with pytest.raises(OutputFileError, match=r"plain is a file, not a folder"):
        write_atomic(tmp_path / "plain" / "deeper" / "a.txt", "x")
    assert (tmp_path / "plain").read_text(encoding="utf-8") == "not a folder"


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs the Linux /proc file system")
def test_a_place_that_cannot_be_written_is_named() -> None:
    # /proc refuses new files even to root (chmod does not stop root).
    with pytest.raises(OutputFileError, match=r"cannot write /proc/optik-out"):
        write_atomic("/proc/optik-out/a.txt", "x")


def test_a_failed_write_keeps_the_old_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = write_atomic(tmp_path / "a.txt", "old")

    def broken(src: object, dst: object) -> None:
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", broken)
    with pytest.raises(OutputFileError, match="disk full"):
        write_atomic(path, "new")
    assert path.read_text(encoding="utf-8") == "old"
    assert not _leftovers(tmp_path)


def test_plan_save_uses_the_same_write(tmp_path: Path) -> None:
    robot = load_problem("planar_2r").robot
    positions = np.array([[1.2, 0.5, 0.0], [1.1, 0.6, 0.0]])
    plan = plan_path(robot, positions, mode="position")
    (tmp_path / "plan.csv").mkdir()
    with pytest.raises(OutputFileError, match="is a folder"):
        plan.save(tmp_path / "plan.csv")
    saved = plan.save(tmp_path / "ok" / "plan.csv")
    assert saved.read_text(encoding="utf-8").count("\n") >= 3
    assert not _leftovers(tmp_path)
