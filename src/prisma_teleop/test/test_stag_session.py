"""The STAG pose session glove_driver replays: its frames, through the shipped pose network and the
pose table, start the grasps of its script in order; the file it writes is one glove_driver reads."""
from __future__ import annotations

import numpy as np

from prisma_teleop.cli import stag_session_main
from prisma_teleop.stag_poses import GraspCommand, OpenCommand, PoseMapper
from prisma_teleop.stag_session import SESSION, stag_session
from prisma_testing.repo_paths import CONFIG
from stag_glove.bundle import load_bundle
from stag_glove.glove_perception_core import GlovePerception
from stag_glove.processing import normalise
from stag_glove.replay_backend import ReplayGloveBackend


def test_the_sessions_poses_start_their_grasps_in_order():
    ds = stag_session(seed=0)
    assert len(ds) == sum(n for _, n in SESSION) == 108
    perception = GlovePerception(pose_bundle=load_bundle(CONFIG / "models" / "glove_pose", "pose"))
    mapper = PoseMapper()
    started = []
    for raw in ds.pressure:
        pressure = normalise(raw)
        estimate = perception.classify_pose(pressure)
        command = mapper.update(estimate.label, estimate.confidence, float(pressure.sum()))
        if command is not None:
            started.append(command.grasp if isinstance(command, GraspCommand) else "open")
    assert started == ["open", "pinch", "open", "power", "open", "lateral", "open"]
    assert isinstance(mapper.current, OpenCommand)  # the session ends with the empty hand


def test_the_file_replays_through_glove_driver(tmp_path, capsys):
    path = tmp_path / "poses.h5"
    assert stag_session_main([str(path), "--seed", "1"]) == 0
    assert "wrote" in capsys.readouterr().out
    backend = ReplayGloveBackend(path, rate_hz=100.0, loop=False)
    frames = [f for t in range(0, 2_000_000_000, 10_000_000) for f in backend.poll(t)]
    assert len(frames) == 108
    assert np.array_equal(frames[20].raw, stag_session(seed=1).pressure[20])
