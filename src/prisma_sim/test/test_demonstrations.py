"""prisma-sim's demonstrations: seeded draws inside their ranges, two sessions written as one valid
LeRobot dataset through prisma_dataset's export, and the command line's refusals."""
from __future__ import annotations

import json

import numpy as np

from prisma_dataset.lerobot_format import read_dataset
from prisma_sim.demonstrations import RANGES, TASK, draw, record_dataset
from prisma_sim.sim_cli import main
from prisma_sim.sim_runner import load_estimator
from prisma_testing.repo_paths import ROOT


def test_draws_are_seeded_and_inside_their_ranges():
    drawn = draw(30, seed=7)
    assert drawn == draw(30, seed=7) and drawn != draw(30, seed=8)
    for name, (low, high) in RANGES.items():
        values = [getattr(d, name) for d in drawn]
        assert low <= min(values) and max(values) <= high
        assert max(values) - min(values) > 0.5 * (high - low)  # they do vary
    demo = drawn[0]
    ball = demo.ball()
    assert ball.finger_contact_rad == {"index": demo.index_contact_rad}
    assert ball.thumb_contact_rad == demo.thumb_contact_rad and ball.stiffness_n_per_mm == demo.stiffness_n_per_mm
    assert demo.script().close_s == demo.close_s and demo.script().sweep_s == 0.0
    assert demo.request().max_speed_rpm == demo.max_speed_rpm


def test_two_demonstrations_make_one_valid_dataset(tmp_path):
    out = tmp_path / "demos"
    lines: list[str] = []
    run = record_dataset(out, 2, seed=1, estimator=load_estimator(ROOT / "config" / "models" / "cnn2"),
                         progress=lines.append)
    assert run.report.ok, run.report.problems
    assert len(lines) == 2 and all("ended input_stale" in line for line in lines)
    dataset = read_dataset(out)
    assert len(dataset.episodes) == 2 and {e.task for e in dataset.episodes} == {TASK}
    for episode, demo, session in zip(dataset.episodes, run.demonstrations, run.sessions):
        # each demonstration closed on its ball and the touch limit held it (2 N, + prisma-sim's 0.15 N)
        assert session["reason"] == "input_stale"
        assert 1.5 < max(session["peak_force_n"]["true"].values()) <= 2.15
        assert episode.length > 3 * 50  # more than 3 s at 50 fps
        # the action closes the fingers past the ball's contact angle, then opens again
        fingers = episode.values["action"][:, 0]
        assert fingers.max() > demo.index_contact_rad and fingers[-1] < 0.5
    notes = json.loads((out / "meta" / "prisma_export.json").read_text())
    recorded = [e["demonstration"] for e in notes["episodes"]]
    assert [r["index_contact_rad"] for r in recorded] == [d.index_contact_rad for d in run.demonstrations]
    assert notes["demonstrations"]["seed"] == 1 and notes["demonstrations"]["ranges"]["closure"] == [0.75, 1.0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["demos"]
    assert not np.array_equal(dataset.episodes[0].values["action"][:50], dataset.episodes[1].values["action"][:50])


def test_the_command_line_refuses_before_running(tmp_path, capsys):
    assert main(["--episodes", "3", "--out", str(tmp_path / "x")]) == 2
    assert "--episodes 3 needs --dataset DIR" in capsys.readouterr().err
    (tmp_path / "ds" / "meta").mkdir(parents=True)
    (tmp_path / "ds" / "meta" / "info.json").write_text("{}")
    assert main(["--dataset", str(tmp_path / "ds"), "--episodes", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "already holds a dataset" in err[0]
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("mine")
    assert main(["--dataset", str(tmp_path / "other")]) == 2
    assert "holds files that are not a LeRobot dataset (notes.txt)" in capsys.readouterr().err
    assert (tmp_path / "other" / "notes.txt").read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ds", "other"]
