"""The judgement of a sample's stamp: zero, ahead of the clock, too old on arrival; one log line per
episode, the refusal's line while it lasts."""
from __future__ import annotations

import pytest

from prisma_common.sample_stamps import AHEAD, OLD, ZERO, StampGate, StampLimits, StampNews, stamp_problem

NS = 1_000_000_000
LIMITS = StampLimits.of_seconds(0.5, 0.25)
NOW = 1_796_664_778 * NS


@pytest.mark.parametrize(("stamp", "now", "kind", "what"), [
    (0, NOW, ZERO, "stamped 0"),
    (NOW - 5 * NS, NOW, OLD, "stamped 5.00 s before it arrived (limit 0.5 s)"),
    (NOW - NS // 2 - 1, NOW, OLD, "stamped 0.50 s before it arrived (limit 0.5 s)"),
    (NOW + NS, NOW, AHEAD, "stamped 1.00 s ahead of this node's clock (limit 0.25 s)"),
])
def test_refused_stamps(stamp, now, kind, what):
    problem = stamp_problem(stamp, now, LIMITS)
    assert problem is not None and (problem.kind, problem.what) == (kind, what)


@pytest.mark.parametrize(("stamp", "now"), [
    (NOW, NOW), (NOW - NS // 2, NOW), (NOW + NS // 4, NOW),  # at the limits
    (NOW - 5 * NS, 0), (0, 0),  # the node's clock not started (use_sim_time before /clock): not judged
    (0, NS // 2),  # a simulation's first sample, its time starting at 0
])
def test_accepted_stamps(stamp, now):
    assert stamp_problem(stamp, now, LIMITS) is None


def test_limits_must_be_positive():
    with pytest.raises(ValueError, match="max_age_ns 0 must be > 0"):
        StampLimits(0, 1)


def test_a_gate_says_it_once_per_episode():
    gate = StampGate("/glove/joint_states", LIMITS)
    news = []
    t = NOW
    for _ in range(600):  # 10 s of a glove stamped 0 at 60 Hz
        t += NS // 60
        accepted, line = gate.judge(0, t)
        assert not accepted
        news += [line] if line else []
    assert news == [StampNews("warning", "/glove/joint_states stamped 0: publish header.stamp (ros2 topic pub: "
                                         "header: auto); its samples are refused until then")]
    assert gate.refused == "/glove/joint_states stamped 0: publish header.stamp (ros2 topic pub: header: auto)"
    for _ in range(600):  # then 5 s old: another reason, one more line
        t += NS // 60
        accepted, line = gate.judge(t - 5 * NS, t)
        assert not accepted
        news += [line] if line else []
    assert len(news) == 2 and news[1].text.startswith("/glove/joint_states stamped 5.00 s before it arrived "
                                                      "(limit 0.5 s): stamp each sample when it is taken")
    assert gate.refused_total == 1200
    t += NS // 60
    assert gate.judge(t, t) == (True, StampNews("info", "/glove/joint_states accepted again (1200 samples refused: "
                                                        "stamped 5.00 s before it arrived)"))
    assert gate.refused is None
    assert gate.judge(t + 1, t + 1) == (True, None)
