"""Sensor watchdog: age by header stamps, silence by receipt, freshness for admission."""
from __future__ import annotations

from prisma_manipulation.watchdog import SensorWatchdog

MS = 1_000_000


def test_watchdog_age_by_header_stamps_and_silence_by_receipt():
    w = SensorWatchdog(100 * MS)
    assert w.check(["taxels/thumb"], 10**9) is None  # not armed: no goal
    w.arm(0)
    assert w.check(["taxels/thumb"], 90 * MS) is None  # grace for a stream not seen yet
    w.reference(100 * MS, 100 * MS)
    assert "taxels/thumb silent for 110 ms" == w.check(["taxels/thumb"], 110 * MS)
    w.arm(200 * MS)
    w.reference(300 * MS, 300 * MS)
    w.sample("taxels/thumb", 250 * MS, 300 * MS)
    assert w.check(["taxels/thumb"], 300 * MS) is None  # 50 ms old
    w.sample("taxels/thumb", 190 * MS, 310 * MS)  # delivered 120 ms late
    assert w.check(["taxels/thumb"], 310 * MS) == "taxels/thumb 110 ms older than /joint_states"
    w.sample("taxels/thumb", 305 * MS, 320 * MS)
    assert w.check(["taxels/thumb"], 320 * MS) is None
    assert w.check(["taxels/thumb"], 450 * MS) == "/joint_states silent for 150 ms"


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
