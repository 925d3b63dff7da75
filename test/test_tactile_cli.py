"""ROS-free tactile CLIs: calibration set, pad plot, pty hub emulator."""
import threading
import time

import numpy as np

from prisma_tactile_driver.calibration import CalibrationSet
from prisma_tactile_driver.cli import calset_main, hub_emulator_main, pad_plot_main
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
