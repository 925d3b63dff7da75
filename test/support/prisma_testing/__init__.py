"""Helpers shared by every test and by bench/: the ROS harness (ros_harness; its streams, sim clock and
hand goals in streams, sim_clock and goals), commands in their own process (node_process), a launch
test's case and emulated hand (launch_case, emulated_launch), the test processes'
priorities (priorities), the repository's paths (repo_paths), the topic table (topic_table), the machine
load (load_harness), the goal soak (goal_soak), the two-host rig (two_hosts, host_probe), a test's
collector process (collector), the JSON-line helper process both drive (json_line_process), the
operator's glove (operator_glove), the URDF's forward kinematics (urdf_kinematics) and a virtual display
(virtual_display).

Not installed (the wheel ships the suite, not its tests): pytest puts test/support on sys.path
(pyproject.toml's `pythonpath`), a bench script puts it there itself. Imported, the package adds its
folder to PYTHONPATH, so that the processes a test or bench script starts (`python -m
prisma_testing.collector`, the launched nodes) import `prisma_testing.<module>` as their parent does."""
from __future__ import annotations

import os
from pathlib import Path

SUPPORT_DIR = str(Path(__file__).resolve().parent.parent)

_path = os.environ.get("PYTHONPATH", "")
if SUPPORT_DIR not in _path.split(os.pathsep):
    os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, (SUPPORT_DIR, _path)))
