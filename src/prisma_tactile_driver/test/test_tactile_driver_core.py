"""Hub core over the sim backend: frames, staleness and diagnostics."""
import numpy as np
import pytest

from prisma_common.diagnostics import ERROR, OK, STALE, WARN
from prisma_common.hand import FINGERS
from prisma_hand_sim.contact_source import ScriptedContactSource
from prisma_hand_sim.pad_model import PadParams
from prisma_tactile_driver.backend import HubReading
from prisma_tactile_driver.sim_backend import SimHubBackend
from prisma_tactile_driver.tactile_driver_core import TactileHub

MS = 1_000_000


class Fixed:
    """A contact source holding one contact on chosen fingers."""

    def __init__(self, contacts):
        self.contacts = contacts

    def contact(self, finger, stamp_ns):
        return self.contacts.get(finger)


def test_sim_backend_publishes_all_fingers_with_consistent_voltages():
    hub = TactileHub(SimHubBackend(ScriptedContactSource()), FINGERS)
    frames = hub.poll(1500 * MS)
    assert [f.finger for f in frames] == list(FINGERS)
    for f in frames:
        assert f.stamp_ns == 1500 * MS
        np.testing.assert_allclose(f.voltages, f.counts * 3.3 / 4096, rtol=1e-6)
    # the thumb is pressed at 1.5 s of its cycle, the little finger (1.6 s later) is not yet
    rest = np.array(PadParams().rest_volts)
    by = {f.finger: f for f in frames}
    assert by["thumb"].voltages[4] > rest[4] + 0.3
    np.testing.assert_allclose(by["little"].voltages, rest, atol=0.02)


def test_vref_scales_voltages():
    hub = TactileHub(SimHubBackend(Fixed({})), ["index"], vref=5.0)
    [frame] = hub.poll(0)
    np.testing.assert_allclose(frame.voltages, frame.counts * 5.0 / 4096, rtol=1e-6)
    with pytest.raises(ValueError, match="vref"):
        TactileHub(SimHubBackend(Fixed({})), ["index"], vref=0)


def test_staleness_levels():
    class Dropping(SimHubBackend):
        def read(self, stamp_ns):
            readings = super().read(stamp_ns)
            if stamp_ns > 100 * MS:
                readings[0].counts.pop("ring")
            if stamp_ns > 500 * MS:
                readings.clear()
            return readings

    hub = TactileHub(Dropping(Fixed({})), FINGERS)
    assert {s.level for s in hub.diagnostics(0)} == {ERROR, STALE}  # nothing read yet
    for step in range(0, 31):
        hub.poll(step * 10 * MS)
    diag = {s.name: s for s in hub.diagnostics(300 * MS)}
    assert diag["tactile_driver: hub"].level == WARN and diag["tactile_driver: ring"].level == STALE
    assert diag["tactile_driver: ring"].message == "stale: no sample for 200 ms"
    assert diag["tactile_driver: thumb"].level == OK
    for step in range(31, 80):
        hub.poll(step * 10 * MS)
    assert hub.stale_fingers(790 * MS) == list(FINGERS)
    assert hub.diagnostics(790 * MS)[0].level == ERROR


def test_a_reading_with_its_own_stamp_is_published_with_it():
    class HubClocked:
        """Two frames drained in one read, stamped by the hub's clock."""

        def read(self, stamp_ns):
            counts = np.full(9, 2048, dtype=np.uint16)
            return [HubReading(41, {"thumb": counts}, stamp_ns - 25 * MS),
                    HubReading(42, {"thumb": counts}, stamp_ns - 15 * MS)]

        def counters(self):
            return {"missed_frames": 3}

        def close(self):
            pass

    hub = TactileHub(HubClocked(), ["thumb"])
    frames = hub.poll(1000 * MS)
    assert [f.stamp_ns for f in frames] == [975 * MS, 985 * MS]
    assert hub.last_stamp_ns["thumb"] == 985 * MS
    assert hub.diagnostics(1000 * MS)[1].values["age_ms"] == "15.0"
    status = hub.diagnostics(1000 * MS)[0]
    assert status.message == "all fingers streaming (3 dropped frames so far)"
    assert hub.take_errors() == [] and hub.link_status().error == ""  # no link_status(): nothing to fail
