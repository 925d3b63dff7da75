"""ROS-free tactile CLIs: calibration set, pad plot, pty hub emulator."""
import os
import select
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from prisma_hand_sim.calibration import CalibrationSet
from prisma_tactile_driver.cli import calset_main, hub_emulator_main, pad_plot_main
from prisma_tactile_driver.pty_hub import PtyHubPort, is_pty_link
from prisma_tactile_driver.serial_backend import SerialHubBackend


def test_calset_writes_a_loadable_set_and_a_plot(tmp_path, capsys):
    out, plot = tmp_path / "cal.npz", tmp_path / "cal.png"
    assert calset_main(["--samples", "3000", "--seed", "2", "--out", str(out), "--plot", str(plot)]) == 0
    cal = CalibrationSet.load(out)
    assert len(cal) == 3000 and plot.stat().st_size > 10_000
    assert "3000 samples" in capsys.readouterr().out


def test_pad_plot(tmp_path):
    assert pad_plot_main(["--out", str(tmp_path / "pad.png")]) == 0
    assert (tmp_path / "pad.png").stat().st_size > 10_000


def test_hub_emulator_feeds_the_serial_backend(tmp_path):
    link = tmp_path / "ttyPRISMA"
    thread = threading.Thread(target=hub_emulator_main,
                              args=(["--link", str(link), "--rate", "200", "--seconds", "0.5"],), daemon=True)
    thread.start()
    deadline = time.monotonic() + 5
    while not link.exists():
        assert time.monotonic() < deadline
        time.sleep(0.005)
    backend = SerialHubBackend(str(link), read_timeout_s=0.01)
    frames = []
    while thread.is_alive():
        frames += backend.poll_frames()
    backend.close()
    thread.join()
    assert len(frames) > 20
    assert np.all(np.diff([f.sequence for f in frames]) == 1)
    assert frames[0].fingers == ("thumb", "index", "middle", "ring", "little")
    assert backend.counters()["crc_errors"] == 0


def test_hub_emulator_nobody_reads_then_sigterm_removes_its_link(tmp_path):
    """Nobody opens the link: the frames beyond the adapter's buffer are dropped, not waited on, so
    SIGTERM (what `ros2 launch` and kill send) ends the run at once, exit 0, and the link is gone."""
    link = tmp_path / "ttyPRISMA"
    code = "import sys; from prisma_tactile_driver.cli import hub_emulator_main as m; sys.exit(m())"
    proc = subprocess.Popen([sys.executable, "-c", code, "--link", str(link), "--rate", "1000", "--seconds", "20"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert select.select([proc.stdout], [], [], 10.0)[0], "the emulator printed nothing in 10 s"
        assert proc.stdout.readline().startswith(f"hub on {link}")
        time.sleep(0.5)  # 500 frames of 78 bytes: ten times what the link holds
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=5) == 0, proc.stderr.read()
        out = proc.stdout.read()
        assert "dropped, nobody read them" in out and "Traceback" not in proc.stderr.read()
        assert list(tmp_path.iterdir()) == []
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.communicate()


# --link: nothing but the emulator's own link is ever replaced or removed --------------------------


def unused_pts_path() -> str:
    """A /dev/pts path no pty has now: what a killed emulator's link points at."""
    n = 9000
    while os.path.exists(f"/dev/pts/{n}"):
        n += 1
    return f"/dev/pts/{n}"


@pytest.mark.parametrize("kind", ["file", "directory", "link to a file", "link to a device"])
def test_link_refuses_anything_but_an_emulator_link(tmp_path, capsys, kind):
    link = tmp_path / "ttyPRISMA"
    target = tmp_path / "notes.txt"
    target.write_text("mine")
    if kind == "file":
        link.write_text("my notes")
    elif kind == "directory":
        link.mkdir()
        (link / "inside").write_text("kept")
    elif kind == "link to a file":
        link.symlink_to(target)
    else:
        link.symlink_to("/dev/null")
    before = (link.is_symlink() and os.readlink(link), link.is_dir(), link.is_file() and link.read_text())
    with pytest.raises(FileExistsError, match="ttyPRISMA is "):
        PtyHubPort(link).open()
    assert hub_emulator_main(["--link", str(link), "--seconds", "0.1"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"prisma-tactile-hub-emulator: error: --link {link} is ") and err.count("\n") == 1
    after = (link.is_symlink() and os.readlink(link), link.is_dir(), link.is_file() and link.read_text())
    assert after == before and target.read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt", "ttyPRISMA"]  # no temporary link left


def test_link_replaces_a_dangling_emulator_link_and_removes_only_its_own(tmp_path):
    link = tmp_path / "ttyPRISMA"
    link.symlink_to(unused_pts_path())  # left by a killed emulator
    assert is_pty_link(link) and not link.exists()
    first = PtyHubPort(link)
    first.open()
    first_pty = os.readlink(link)
    assert first_pty.startswith("/dev/pts/") and os.path.exists(first_pty)
    # a second emulator takes the live link over; the first one's close leaves it alone
    second = PtyHubPort(link)
    second.open()
    second_pty = os.readlink(link)
    assert second_pty != first_pty
    first.close()
    assert os.readlink(link) == second_pty
    second.close()
    assert not link.is_symlink()
    # a link replaced by a user's file meanwhile is not removed either
    third = PtyHubPort(link)
    third.open()
    link.unlink()
    link.write_text("mine now")
    third.close()
    assert link.read_text() == "mine now"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ttyPRISMA"]


def test_link_in_a_missing_directory_is_named(tmp_path, capsys):
    assert hub_emulator_main(["--link", str(tmp_path / "no" / "tty")]) == 2
    assert f"the directory {tmp_path / 'no'} does not exist" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
