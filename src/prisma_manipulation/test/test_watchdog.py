"""Sensor watchdog: age by header stamps, silence by receipt, freshness for admission."""
from __future__ import annotations

from prisma_manipulation.watchdog import SensorWatchdog

MS = 1_000_000


def test_watchdog_age_by_header_stamps_and_silence_by_receipt():
    w = SensorWatchdog(100 * MS)
    assert w.check(["taxels/thumb"], 10**9) is None  # not armed: no goal
    w.arm(0)
    for t in (20, 40, 60, 80):
        assert w.check(["taxels/thumb"], t * MS) is None  # grace for a stream not seen yet
    w.reference(100 * MS, 100 * MS)
    assert w.check(["taxels/thumb"], 100 * MS) is None
    assert "taxels/thumb silent for 110 ms" == w.check(["taxels/thumb"], 110 * MS)
    w.arm(200 * MS)
    w.check(["taxels/thumb"], 220 * MS)
    w.check(["taxels/thumb"], 260 * MS)
    w.reference(300 * MS, 300 * MS)
    w.sample("taxels/thumb", 250 * MS, 300 * MS)
    assert w.check(["taxels/thumb"], 300 * MS) is None  # 50 ms old
    w.sample("taxels/thumb", 190 * MS, 310 * MS)  # delivered 120 ms late
    assert w.check(["taxels/thumb"], 310 * MS) == "taxels/thumb 110 ms older than /joint_states"
    w.sample("taxels/thumb", 305 * MS, 320 * MS)
    assert w.check(["taxels/thumb"], 320 * MS) is None
    for t in range(340, 420, 20):  # the watchdog ticks every 20 ms: taxels arrive, /joint_states stops
        w.sample("taxels/thumb", t * MS, t * MS)
        assert w.check(["taxels/thumb"], t * MS) is None
    assert w.check(["taxels/thumb"], 420 * MS) == "/joint_states silent for 120 ms"


def tick(w: SensorWatchdog, streams: list[str], start_ms: int, end_ms: int, deliver: bool = True) -> list:
    """Checks every 20 ms from start_ms to end_ms (exclusive), the streams delivering just before each."""
    verdicts = []
    for t in range(start_ms, end_ms, 20):
        if deliver:
            w.reference(t * MS, t * MS)
            for name in streams:
                w.sample(name, t * MS, t * MS)
        verdicts.append(w.check(streams, t * MS))
    return verdicts


def test_a_check_held_up_with_the_node_does_not_count_the_hold_up_as_silence():
    w = SensorWatchdog(100 * MS)
    w.arm(0)
    assert tick(w, ["taxels/thumb"], 0, 200) == [None] * 10
    # the process got no CPU from 180 to 330 ms: the watchdog tick comes first, the messages that
    # arrived meanwhile are still queued behind it
    assert w.check(["taxels/thumb"], 330 * MS) is None  # 150 ms since the last receipts
    w.reference(329 * MS, 331 * MS)  # then the queue drains: the streams were not silent
    w.sample("taxels/thumb", 328 * MS, 332 * MS)
    assert tick(w, ["taxels/thumb"], 350, 450) == [None] * 5
    # a stream that really stopped at the hold-up is reported a stale window after the node resumed
    w = SensorWatchdog(100 * MS)
    w.arm(0)
    tick(w, ["taxels/thumb"], 0, 200)
    assert w.check(["taxels/thumb"], 330 * MS) is None
    verdicts = [(t, w.check(["taxels/thumb"], t * MS)) for t in range(350, 470, 20)]
    assert [t for t, v in verdicts if v is None] == [350, 370, 390, 410, 430]
    assert verdicts[-1] == (450, "/joint_states silent for 270 ms")


def test_after_a_hold_up_a_stream_that_has_not_delivered_yet_is_not_judged_by_its_stamp():
    # the whole machine stood still from 180 to 585 ms; the motor driver ran first after it, so the
    # /joint_states stamped 585 ms is taken, and checked, before any taxel frame of after the hold-up
    # (a loaded pass: "taxels/thumb 405 ms older than /joint_states")
    streams = ["taxels/thumb"]
    w = SensorWatchdog(100 * MS)
    w.arm(0)
    tick(w, streams, 0, 200)
    w.reference(585 * MS, 586 * MS)
    assert w.check(streams, 586 * MS) is None
    w.sample("taxels/thumb", 587 * MS, 588 * MS)  # the tactile driver's first frame after it
    assert w.check(streams, 590 * MS) is None
    assert tick(w, streams, 600, 700) == [None] * 5
    # a frame from before the hold-up, delivered after it, is as stale as ever
    w = SensorWatchdog(100 * MS)
    w.arm(0)
    tick(w, streams, 0, 200)
    w.reference(585 * MS, 586 * MS)
    w.check(streams, 586 * MS)
    w.sample("taxels/thumb", 181 * MS, 588 * MS)
    assert w.check(streams, 590 * MS) == "taxels/thumb 404 ms older than /joint_states"
    # a stream that stopped at the hold-up is reported silent a stale window after the node resumed
    w = SensorWatchdog(100 * MS)
    w.arm(0)
    tick(w, streams, 0, 200)
    verdicts = []
    for t in range(586, 720, 20):
        w.reference(t * MS, t * MS)
        verdicts.append((t, w.check(streams, t * MS)))
    assert [t for t, v in verdicts if v is None] == [586, 606, 626, 646, 666, 686]
    assert verdicts[-1] == (706, "taxels/thumb silent for 526 ms")


def test_after_a_hold_up_an_input_that_has_not_delivered_yet_is_not_judged_by_its_stamp():
    w = SensorWatchdog(100 * MS)
    w.arm(0)
    for t in range(0, 200, 20):
        w.reference(t * MS, t * MS)
        w.sample("targets", t * MS, t * MS)
        assert w.check([], t * MS) is None and w.check_input("targets", 200 * MS, t * MS) is None
    w.reference(585 * MS, 586 * MS)  # after a 405 ms hold-up, before the glove's next target
    assert w.check([], 586 * MS) is None
    assert w.check_input("targets", 200 * MS, 586 * MS) is None
    assert w.check_input("targets", 200 * MS, 787 * MS) == "targets silent for 607 ms"
    w.sample("targets", 360 * MS, 790 * MS)  # delivered after it, but from during the hold-up
    assert w.check_input("targets", 200 * MS, 790 * MS) == "targets 225 ms older than /joint_states"


def test_a_node_held_up_check_after_check_is_not_forgiven():
    w = SensorWatchdog(100 * MS)
    w.arm(0)
    tick(w, ["taxels/thumb"], 0, 200)
    assert w.check(["taxels/thumb"], 260 * MS) is None  # held up 80 ms: forgiven
    assert w.check(["taxels/thumb"], 330 * MS) == "/joint_states silent for 150 ms"  # held up again: judged


def test_watchdog_freshness_for_admission_has_no_grace():
    w = SensorWatchdog(100 * MS)
    assert w.fresh(["taxels/thumb"], 0) == "no /joint_states received yet"
    w.reference(10 * MS, 10 * MS)
    assert w.fresh(["taxels/thumb"], 10 * MS) == "no taxels/thumb received yet"  # no grace: never seen
    w.sample("taxels/thumb", 10 * MS, 12 * MS)
    assert w.fresh(["taxels/thumb"], 20 * MS) is None
    assert w.fresh(["taxels/thumb", "wrench/thumb"], 20 * MS) == "no wrench/thumb received yet"
    assert w.fresh(["taxels/thumb"], 113 * MS) == "/joint_states silent for 103 ms"
    w.reference(120 * MS, 120 * MS)
    assert w.fresh(["taxels/thumb"], 120 * MS) == "taxels/thumb silent for 108 ms"
    w.sample("taxels/thumb", 15 * MS, 120 * MS)  # arrives now, 105 ms old
    assert w.fresh(["taxels/thumb"], 120 * MS) == "taxels/thumb 105 ms older than /joint_states"
    assert w.check(["taxels/thumb"], 120 * MS) is None  # admission only: nothing is armed


def test_a_refused_sample_is_named_until_one_is_accepted():
    w = SensorWatchdog(100 * MS)
    w.reference(0, 0)
    w.sample("taxels/thumb", 0, 0)
    why = "taxels/thumb stamped 0: publish header.stamp (ros2 topic pub: header: auto)"
    w.refuse("taxels/thumb", why, 10 * MS)
    assert w.fresh(["taxels/thumb"], 20 * MS) == why
    w.arm(20 * MS)
    assert w.check(["taxels/thumb"], 30 * MS) == why
    w.sample("taxels/thumb", 40 * MS, 40 * MS)
    w.reference(40 * MS, 40 * MS)
    assert w.check(["taxels/thumb"], 50 * MS) is None and w.fresh(["taxels/thumb"], 50 * MS) is None
    w.refuse("/joint_states", "/joint_states stamped 0: publish header.stamp", 60 * MS)
    assert w.check(["taxels/thumb"], 70 * MS) == "/joint_states stamped 0: publish header.stamp"


def test_an_input_is_asked_before_admission_only_once_it_came():
    w = SensorWatchdog(100 * MS)
    w.reference(1000 * MS, 1000 * MS)
    assert w.input_fresh("teleop_target", 150 * MS, 1000 * MS, "targets") is None  # not come: the goal waits
    w.sample("teleop_target", 990 * MS, 995 * MS)
    assert w.input_fresh("teleop_target", 150 * MS, 1000 * MS, "targets") is None
    w.sample("teleop_target", 800 * MS, 1005 * MS)
    assert w.input_fresh("teleop_target", 150 * MS, 1010 * MS, "targets") == "targets 200 ms older than /joint_states"
    assert w.input_fresh("teleop_target", 150 * MS, 1200 * MS, "targets") is None  # silent since: it waits again
    w.refuse("teleop_target", "targets stamped 0: publish header.stamp", 1300 * MS)
    assert w.input_fresh("teleop_target", 150 * MS, 1400 * MS, "targets") == "targets stamped 0: publish header.stamp"
    assert w.input_fresh("teleop_target", 150 * MS, 1500 * MS, "targets") is None  # long ago
