"""Scan alignment: one step per complete scan, late parts dropped."""
from __future__ import annotations

from prisma_manipulation.sample_alignment import SampleAligner


def test_aligner_steps_once_per_complete_scan_and_drops_late_parts():
    a = SampleAligner()
    need = {("taxels", "thumb"), ("wrench", "thumb")}
    a.add(("taxels", "thumb"), 10, "t10")
    assert a.ready(need) is None
    a.add(("taxels", "thumb"), 20, "t20")
    a.add(("wrench", "thumb"), 10, "w10")
    assert a.ready(need) == (10, {("taxels", "thumb"): "t10", ("wrench", "thumb"): "w10"})
    assert a.ready(need) is None  # consumed
    a.add(("wrench", "thumb"), 20, "w20")
    assert a.ready(need)[0] == 20
    a.add(("wrench", "thumb"), 15, "late")  # older than a consumed scan: ignored
    assert a.ready({("wrench", "thumb")}) is None
