"""The emulated hand's console scripts as subprocesses: prisma-hand-emulator refusing a missing hand,
a file as its directory or an occupied control socket, answering faults and stopping on SIGINT,
removing what it made on SIGTERM; prisma-hand-fault refusing faults of the other tactile link.
"""
from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import time

from prisma_testing.emulator_rig import (
    DEVICES,
    EMULATOR_ENV,
    run_cli,
)
from prisma_testing.node_process import console_script


# ---- console scripts --------------------------------------------------------------------------
def test_cli_refuses_a_missing_hand_and_a_file_as_dir(tmp_path):
    done = run_cli("prisma-hand-fault", "--dir", str(tmp_path), "status")  # an empty directory
    assert done.returncode == 2 and "no emulated hand at" in done.stderr and "Traceback" not in done.stderr
    # the way to the emulator a launch started: its emulator_dir is this --dir
    assert "hardware:=emulated emulator_dir:=DIR` is reached with `prisma-hand-fault --dir DIR ...`" in done.stderr
    assert f"prisma-hand-emulator --dir {tmp_path}`" in done.stderr
    (regular := tmp_path / "a_file").write_text("x")
    done = run_cli("prisma-hand-emulator", "--dir", str(regular), "--seconds", "1")
    assert done.returncode == 2 and str(regular) in done.stderr and "Traceback" not in done.stderr


def test_cli_emulator_refuses_an_occupied_control_socket_path(tmp_path):
    """Something at control.sock: exit 2 naming it, and the devices already made are removed."""
    (tmp_path / "control.sock").write_text("x")
    done = run_cli("prisma-hand-emulator", "--dir", str(tmp_path), "--seconds", "1")
    assert os.listdir(tmp_path) == ["control.sock"]
    assert done.returncode == 2 and "control.sock" in done.stderr and "Traceback" not in done.stderr


def test_cli_running_emulator_answers_faults_and_stops_on_sigint(tmp_path):
    d = str(tmp_path)
    proc = subprocess.Popen([console_script("prisma-hand-emulator"), "--dir", d, "--seconds", "20"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=EMULATOR_ENV)
    try:
        assert select.select([proc.stdout], [], [], 60.0)[0], "the emulator printed nothing in 60 s"
        assert proc.stdout.readline().startswith("emulated hand (pinch_ball, 100 Hz)")
        done = run_cli("prisma-hand-fault", "--dir", d, "status")
        assert done.returncode == 0, done.stderr
        status = json.loads(done.stdout)
        assert status["world"] == "pinch_ball" and status["hub"]["plugged"] is True
        done = run_cli("prisma-hand-fault", "--dir", d, "servo-error", "--motor", "fingers", "--bit", "9")
        assert done.returncode == 2 and "bit 9" in done.stderr and "Traceback" not in done.stderr
        done = run_cli("prisma-hand-fault", "--dir", d, "servo-error", "--motor", "fingers", "--bit", "overload")
        assert done.returncode == 0 and "overload" in done.stdout
        status = json.loads(run_cli("prisma-hand-fault", "--dir", d, "status").stdout)
        assert status["servos"]["fingers"]["hardware_error"] == 0x20
        start = time.monotonic()
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=5) == 0 and time.monotonic() - start < 2.5  # lingers 1 s by default
        assert "emulated hand stopped after" in proc.stdout.read()
        assert os.listdir(d) == []  # hub, servos and control.sock removed
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.communicate()


def test_cli_on_sigterm_removes_what_it_made_and_refuses_faults_of_the_other_link(tmp_path):
    """`--tactile-link i2c`: the bus socket and no hub; hub-unplug is refused in one line naming the
    link; SIGTERM (what `ros2 launch` sends) removes the devices and the directories it created."""
    d = tmp_path / "made" / "hand"
    proc = subprocess.Popen([console_script("prisma-hand-emulator"), "--dir", str(d), "--tactile-link", "i2c",
                             "--linger", "0", "--seconds", "20"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=EMULATOR_ENV)
    try:
        assert select.select([proc.stdout], [], [], 60.0)[0], "the emulator printed nothing in 60 s"
        assert f"i2c {d / 'i2c.sock'}" in proc.stdout.readline()
        assert sorted(os.listdir(d)) == sorted(DEVICES["i2c"])
        done = run_cli("prisma-hand-fault", "--dir", str(d), "hub-unplug", "--seconds", "1")
        lines = done.stderr.strip().splitlines()
        assert done.returncode == 2 and len(lines) == 1 and "Traceback" not in done.stderr, done.stderr
        assert lines[0].startswith("prisma-hand-fault: error: hub-unplug: ") and "tactile link i2c" in lines[0]
        assert lines[0].count("hub-unplug") == 1, lines[0]  # the command named once, not once per layer
        status = json.loads(run_cli("prisma-hand-fault", "--dir", str(d), "status").stdout)
        assert status["tactile_link"] == "i2c" and "hub" not in status and status["i2c"]["nacks"] == 0
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=5) == 0
        assert os.listdir(tmp_path) == []
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.communicate()
