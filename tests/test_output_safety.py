"""Outputs are regular files: a device node, a FIFO or a link pointing out of its folder at
an output path is refused and left as it was; a link inside its folder is written through.
The nodes are made in the test's own folder, never on the machine's."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import numpy as np
import pytest

from mca_drake.app import cli
from mca_drake.atomic_io import atomic_write_text, check_writable
from mca_drake.references.recording import Recording, save_recording


def _char_device(path: Path) -> Path:
    try:  # the null device's numbers, made here: writing it would replace only this node
        os.mknod(path, stat.S_IFCHR | 0o600, os.makedev(1, 3))
    except PermissionError:
        pytest.skip("making a device node needs root")
    return path


@pytest.mark.parametrize("kind", ["fifo", "char_device", "socket"])
def test_a_special_file_is_refused_and_left_alone(tmp_path, kind):
    path = tmp_path / kind
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "char_device":
        _char_device(path)
    else:
        import socket

        server = socket.socket(socket.AF_UNIX)
        server.bind(str(path))
        server.close()
    before = os.stat(path).st_mode
    with pytest.raises(OSError, match=r"refusing to write .*not a regular file"):
        atomic_write_text(path, "data")
    with pytest.raises(OSError, match="not a regular file"):
        check_writable(path)
    assert os.stat(path).st_mode == before  # still the node it was


def test_a_link_out_of_its_folder_is_refused(tmp_path):
    (tmp_path / "out").mkdir()
    elsewhere = tmp_path / "elsewhere.txt"
    elsewhere.write_text("keep")
    link = tmp_path / "out" / "summary.json"
    link.symlink_to(elsewhere)
    with pytest.raises(OSError, match=r"symbolic link .*outside"):
        atomic_write_text(link, "data")
    assert elsewhere.read_text() == "keep" and link.is_symlink()


def test_a_link_to_a_device_is_refused(tmp_path):
    device = _char_device(tmp_path / "null")
    link = tmp_path / "plot.png"
    link.symlink_to(device)
    with pytest.raises(OSError, match=r"a link to .*character device"):
        atomic_write_text(link, "data")
    assert stat.S_ISCHR(os.stat(device).st_mode) and link.is_symlink()


def test_a_link_inside_its_folder_is_written_through(tmp_path):
    real = tmp_path / "run_3.json"
    real.write_text("old")
    link = tmp_path / "latest.json"
    link.symlink_to(real.name)
    assert atomic_write_text(link, "new") == link
    assert link.is_symlink() and real.read_text() == "new"


def test_the_command_refuses_a_fifo_output_in_one_line(tmp_path, capsys):
    t = np.arange(0, 2.0, 0.01)
    recording = Recording(t, np.zeros((t.size, 3)), np.tile([0.0, 0.0, 9.81], (t.size, 1)))
    csv = save_recording(tmp_path / "ok.csv", recording)
    fifo = tmp_path / "plot.png"
    os.mkfifo(fifo)
    assert cli.main(["plot-recording", str(csv), "--out", str(fifo)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "FIFO" in err
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)
