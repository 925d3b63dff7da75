"""Episodes as the teleop core marks them: engaging starts one, letting go ends it with the outcome
derived from the goal's end, the goal ending for good ends it as a failure, the operator's service
starts one with a task and ends it with their outcome, and what it refuses."""
from __future__ import annotations

import pytest

from prisma_common.diagnostics import OK
from prisma_teleop.episodes import END, FAILURE, START, SUCCESS, EpisodeMarker, EpisodeMarks, EpisodeRefused
from prisma_teleop.node_config import TeleopConfig
from prisma_teleop.retargeting import nominal_calibration
from prisma_teleop.synthetic_glove_core import Synergies, hand_pose
from prisma_teleop.teleop_core import RESUME_SAMPLES, HandPoseTeleop, SendGoal, StagTeleop

NS = 1_000_000_000
PERIOD_NS = NS // 60
CAL = nominal_calibration()


def markers(actions: list) -> list[EpisodeMarker]:
    return [a for a in actions if isinstance(a, EpisodeMarker)]


def feed(core: HandPoseTeleop, t_ns: int, n: int) -> tuple[int, list]:
    actions: list = []
    for _ in range(n):
        t_ns += PERIOD_NS
        actions += core.on_sample(t_ns, hand_pose(Synergies(0.5, 0.5, 0.0), CAL), t_ns)[1]
    return t_ns, actions


def test_engaged_at_start_the_first_episode_starts_at_once_and_letting_go_ends_it_a_success():
    core = HandPoseTeleop(TeleopConfig(engage_at_start=True, episode_task="pinch the ball"), CAL)
    (start,) = core.begin(2 * NS)
    assert start == EpisodeMarker(2 * NS, 0, START, "pinch the ball", "", "engaged")
    t, actions = feed(core, 2 * NS, RESUME_SAMPLES)
    assert [type(a) for a in actions if isinstance(a, SendGoal)] == [SendGoal]  # the goal runs
    message, actions = core.engage(False, t + NS)
    (end,) = markers(actions)
    assert end == EpisodeMarker(t + NS, 0, END, "pinch the ball", SUCCESS, "let go; a goal was running")
    # its cancel's end comes after the episode: nothing more is marked
    assert markers(core.on_goal_ended("canceled", True, t + NS + 1000)) == []
    _, actions = core.engage(True, t + 2 * NS)
    assert markers(actions) == [EpisodeMarker(t + 2 * NS, 1, START, "pinch the ball", "", "engaged")]


def test_not_engaged_at_start_no_episode_until_engaging_and_engaging_twice_starts_one():
    core = HandPoseTeleop(TeleopConfig(), CAL)
    assert core.begin(NS) == []
    _, actions = core.engage(True, 3 * NS)
    assert [m.episode for m in markers(actions)] == [0]
    assert markers(core.engage(True, 4 * NS)[1]) == []  # already engaged, episode 0 open
    assert markers(core.engage(False, 5 * NS)[1])[0].outcome == FAILURE  # no goal ran
    assert markers(core.engage(False, 6 * NS)[1]) == []  # nothing open


def test_the_goal_ending_for_good_ends_the_episode_a_failure_with_its_reason():
    core = HandPoseTeleop(TeleopConfig(engage_at_start=True), CAL)
    core.begin(NS)
    t, _ = feed(core, NS, RESUME_SAMPLES)
    actions = core.on_goal_ended("sensor_stale: taxels/index silent for 110 ms", False, t)
    (end,) = markers(actions)
    assert (end.episode, end.event, end.outcome, end.reason, end.stamp_ns) == (
        0, END, FAILURE, "the goal ended sensor_stale: taxels/index silent for 110 ms", t)
    assert not core.engaged and core.episodes.open is None


def test_input_stale_does_not_end_the_episode_but_letting_go_while_silent_is_a_failure():
    core = HandPoseTeleop(TeleopConfig(engage_at_start=True), CAL)
    core.begin(NS)
    t, _ = feed(core, NS, RESUME_SAMPLES)
    stale = "input_stale: prisma/teleop/motor_targets silent for 160 ms"
    assert markers(core.on_goal_ended(stale, False, t + NS // 2)) == []
    assert core.episodes.open is not None
    (end,) = markers(core.engage(False, t + NS)[1])
    assert (end.outcome, end.reason) == (FAILURE, f"let go; the last goal ended {stale}")


def test_the_operators_service_starts_with_a_task_and_ends_with_their_outcome():
    core = HandPoseTeleop(TeleopConfig(engage_at_start=True), CAL)
    t, _ = feed(core, NS, RESUME_SAMPLES)  # engaged, a goal running, no episode (begin not called)
    done, message, index, actions = core.mark_episode("start", t, task="lift the card")
    assert (done, index, message) == (True, 0, "episode 0 started (the operator): lift the card")
    assert markers(actions) == [EpisodeMarker(t, 0, START, "lift the card", "", "the operator")]
    done, message, index, actions = core.mark_episode("start", t + 1, task="again")
    assert (done, index, actions) == (False, 0, [])
    assert message == "episode 0 (lift the card) is open: end it first (event 'end', outcome success or failure)"
    done, message, index, actions = core.mark_episode("end", t + 5 * NS, outcome="failure")
    assert (done, index) == (True, 0)
    assert markers(actions) == [EpisodeMarker(t + 5 * NS, 0, END, "lift the card", FAILURE, "the operator")]
    assert core.engaged  # the service marks; engagement stays as it is
    done, message, index, _ = core.mark_episode("end", t + 6 * NS)
    assert (done, index, message) == (False, 1, "no episode is open: start one (event 'start', or engage)")
    # without an outcome it is derived: the goal still runs
    core.mark_episode("start", t + 7 * NS)
    _, message, index, actions = core.mark_episode("end", t + 8 * NS)
    assert (index, markers(actions)[0].outcome, markers(actions)[0].task) == (
        1, SUCCESS, "teleoperate the PRISMA hand")
    assert message == "episode 1 ended success (the operator; a goal was running): teleoperate the PRISMA hand"


@pytest.mark.parametrize(("event", "task", "outcome", "why"), [
    ("begin", "", "", "event 'begin': give start or end"),
    ("end", "", "great", "outcome 'great': give success or failure, or nothing to derive it from the goal's end"),
    ("end", "other", "", "task 'other' given to an end: the task is the start's (pinch)"),
])
def test_wrong_service_requests_are_refused_naming_the_value(event, task, outcome, why):
    marks = EpisodeMarks("pinch")
    marks.mark("start", NS)
    with pytest.raises(EpisodeRefused) as caught:
        marks.mark(event, 2 * NS, task, outcome)
    assert str(caught.value) == why
    assert marks.open is not None and marks.open.episode == 0


def test_a_start_with_an_outcome_is_refused():
    with pytest.raises(EpisodeRefused, match="outcome 'success' given to a start"):
        EpisodeMarks().mark("start", NS, outcome="success")


def test_stag_a_grasp_that_ended_succeeded_is_a_success_and_a_refusal_a_failure():
    core = StagTeleop(TeleopConfig(input="stag", engage_at_start=True))
    core.begin(NS)
    core.episodes.goal_started()
    core.on_goal_ended("succeeded", True, 2 * NS)
    (end,) = markers(core.engage(False, 3 * NS)[1])
    assert (end.outcome, end.reason) == (SUCCESS, "let go; the last goal ended succeeded")
    core.engage(True, 4 * NS)
    core.episodes.goal_started()
    core.on_goal_ended("not_ready: joint_states not received yet", False, 5 * NS)
    (end,) = markers(core.engage(False, 6 * NS)[1])
    assert (end.episode, end.outcome) == (1, FAILURE)


def test_the_status_says_the_open_episode_and_the_last_one():
    core = HandPoseTeleop(TeleopConfig(engage_at_start=True, episode_task="pinch the ball"), CAL)
    core.begin(NS)
    t, _ = feed(core, NS, 60)
    status = core.diagnostics(t)
    assert status.level == OK
    assert status.values["episode"] == "0 open for 1.0 s: pinch the ball"
    assert status.values["last_episode"] == "none"
    core.engage(False, t)
    values = core.diagnostics(t + NS).values
    assert values["episode"] == "none open"
    assert values["last_episode"] == "episode 0 ended success (let go; a goal was running): pinch the ball"


def test_episode_task_changes_at_run_time_and_may_not_be_empty():
    core = HandPoseTeleop(TeleopConfig(), CAL)
    core.reconfigure(TeleopConfig(episode_task="power grasp"))
    _, actions = core.engage(True, NS)
    assert markers(actions)[0].task == "power grasp"
    from prisma_common.parameters import ParameterError
    with pytest.raises(ParameterError, match="episode_task"):
        TeleopConfig(episode_task="  ").validate()
