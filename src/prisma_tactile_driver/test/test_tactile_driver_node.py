"""tactile_driver node on real rclpy over DDS: topics, voltages, diagnostics, parameters.

Sim-time tests drive the node's timers with a /clock the test publishes, so stamps are exact.
"""
import sys

import numpy as np
import pytest

from prisma_testing.repo_paths import CONFIG
from prisma_testing.ros_harness import require_ros, stamp_ns

require_ros()

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402
from prisma_msgs.msg import HandTaxels, TaxelArray  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from prisma_common.hand import FINGERS
from prisma_common.parameters import ParameterError
from prisma_hand_sim.contact_source import ScriptedContactSource
from prisma_hand_sim.pad_model import PadContact, PadParams
from prisma_tactile_driver.node_config import TactileDriverConfig
from prisma_tactile_driver.protocol import encode_frame
from prisma_tactile_driver.sim_backend import SimHubBackend

CONFIG = CONFIG / "tactile_driver.yaml"


@pytest.fixture
def node_cls():
    from prisma_tactile_driver.tactile_driver_node import TactileDriverNode
    return TactileDriverNode


def diag_by_name(msg):
    return {s.name: s for s in msg.status}


def test_config_yaml_matches_declared_defaults():
    import yaml
    params = yaml.safe_load(CONFIG.read_text())["/**/tactile_driver"]["ros__parameters"]  # any namespace
    assert params == TactileDriverConfig().as_parameters()


def test_sim_publishes_five_taxel_topics_with_pad_model_voltages(ros, node_cls):
    seen = {f: ros.collect(TaxelArray, f"/prisma/{f}/taxels") for f in FINGERS}
    hands = ros.collect(HandTaxels, "/prisma/hand/taxels")
    ros.node(node_cls, params_files=[CONFIG], sim_time=True)
    start = ros.now_ns()
    ros.advance(1.99, step=0.01)  # scans at the start instant, then every 10 ms: 200
    assert ros.spin_until(lambda: all(len(m) == 200 for m in seen.values()) and len(hands) == 200)
    # the same pad models and scripted contacts, driven with the stamps the node used
    reference = SimHubBackend(ScriptedContactSource(), FINGERS, seed=0)
    stamps = [stamp_ns(m) for m in seen["thumb"]]
    assert len(stamps) == 200 and np.all(np.diff(stamps) == 10_000_000)
    assert start <= stamps[0] <= start + 10_000_000  # the first scan when the clock starts
    expected = [reference.read(s)[0].counts for s in stamps]
    for finger, msgs in seen.items():
        assert [stamp_ns(m) for m in msgs] == stamps
        assert all(m.finger == finger and m.header.frame_id == f"prisma_{finger}_pad" for m in msgs)
        counts = np.array([m.counts for m in msgs])
        np.testing.assert_array_equal(counts, [e[finger] for e in expected])
        np.testing.assert_allclose(np.array([m.voltages for m in msgs]), counts * 3.3 / 4096, rtol=1e-6)
    # the same samples once per scan on the per-hand topic, stamped with the scan
    assert [stamp_ns(h) for h in hands] == stamps
    for k, hand in enumerate(hands):
        assert list(hand.samples) == [seen[f][k] for f in FINGERS]
    # the scripted cycle pressed the thumb's centre in the second second
    pressed = np.array(seen["thumb"][-1].voltages)
    assert pressed[4] > np.array(seen["thumb"][0].voltages)[4] + 0.5


def test_diagnostics_at_1hz_with_counters(ros, node_cls):
    diagnostics = ros.collect(DiagnosticArray, "/diagnostics")
    ros.node(node_cls, sim_time=True)
    ros.advance(3.0, step=0.01)  # diagnostics at the start instant and 1 s, 2 s, 3 s after it
    assert ros.spin_until(lambda: len(diagnostics) == 4)
    ros.spin_for(0.1)
    assert len(diagnostics) == 4
    assert [stamp_ns(m) - stamp_ns(diagnostics[0]) for m in diagnostics] == [0, 10**9, 2 * 10**9, 3 * 10**9]
    status = diag_by_name(diagnostics[-1])
    hub = status["tactile_driver: hub"]
    assert hub.level == DiagnosticStatus.OK
    assert {kv.key: kv.value for kv in hub.values}["scans"] == "301"  # the start instant and 300 periods
    assert status["tactile_driver: ring"].level == DiagnosticStatus.OK
    values = {kv.key: kv.value for kv in status["tactile_driver: index"].values}
    assert values == {"samples": "301", "age_ms": "0.0"}
    # no tare here: zeroing the fingertip forces is the force estimator's ~/bias
    assert "/tactile_driver/tare" not in dict(ros.probe.get_service_names_and_types())
    assert hub.hardware_id == "sim/scripted"


def test_two_hands_diagnostics_say_which_hand(ros, node_cls):
    """/diagnostics is one topic for every hand: under a namespace the names and hardware IDs carry it,
    so that a robot monitor keeps the left hand's hub apart from the right one's."""
    diagnostics = ros.collect(DiagnosticArray, "/diagnostics")
    for side in ("left", "right"):
        ros.node(node_cls, namespace=side, params={"contact_source": "hand_world"}, sim_time=True)
    ros.advance(1.0, step=0.01)
    assert ros.spin_until(lambda: len(diagnostics) >= 4)  # two per hand: the start instant and 1 s
    named = {s.name: s.hardware_id for m in diagnostics for s in m.status}
    for side in ("left", "right"):
        assert named[f"{side}/tactile_driver: hub"] == f"{side}/sim/hand_world/pinch_ball"
        assert {f"{side}/tactile_driver: {f}" for f in FINGERS} <= set(named)
    assert len(named) == 2 * (1 + len(FINGERS))  # none unprefixed, none shared


@pytest.mark.parametrize("override, name, bad", [
    ({"backend": "usb"}, "backend", "usb"),
    ({"finger_channels": [0, 1, 2, 2, 4]}, "finger_channels", "[0, 1, 2, 2, 4]"),
    ({"vref": 0.0}, "vref", "0.0"),
    ({"vref": -3.3}, "vref", "-3.3"),
    ({"contact_source": "glove"}, "contact_source", "glove"),
])
def test_invalid_parameters_fail_at_start_naming_the_parameter(ros, node_cls, override, name, bad):
    with pytest.raises(ParameterError) as info:
        ros.node(node_cls, params=override)
    assert f"'{name}'" in str(info.value) and bad in str(info.value)


def test_stale_timeout_changes_at_run_time_the_link_parameters_do_not(ros, node_cls):
    node = ros.node(node_cls)
    assert node.hub.stale_timeout_ns == 100_000_000
    (ok,) = ros.set_parameters("/tactile_driver", stale_timeout=0.5)
    assert ok.successful and node.hub.stale_timeout_ns == 500_000_000 and node.config.stale_timeout == 0.5
    (too_long,) = ros.set_parameters("/tactile_driver", stale_timeout=20.0)
    assert not too_long.successful and too_long.reason.startswith("Parameter stale_timeout out of range")
    for name, value in (("backend", "serial"), ("rate_hz", 50.0), ("sim_seed", 10)):
        (refused,) = ros.set_parameters("/tactile_driver", **{name: value})
        assert (refused.successful, refused.reason) == (False, f"Trying to set a read-only parameter: {name}.")
    assert node.hub.stale_timeout_ns == 500_000_000 and node.config.rate_hz == 100.0


def test_i2c_nacking_finger_goes_stale_while_four_keep_publishing(ros, node_cls, monkeypatch):
    import smbus2

    from prisma_tactile_driver.i2c_emulator import EmulatedSMBus, five_finger_bus
    values = {ch: np.arange(9) * 400 + ch for ch in range(5)}
    bus = five_finger_bus(values)
    bus.adcs[3].failing = True  # the ring finger's ADC (channel 3) never acknowledges
    opened = []
    monkeypatch.setattr(smbus2, "SMBus", lambda n: opened.append(n) or EmulatedSMBus(bus))
    seen = {f: ros.collect(TaxelArray, f"/prisma/{f}/taxels") for f in FINGERS}
    diagnostics = ros.collect(DiagnosticArray, "/diagnostics")
    ros.node(node_cls, params={"backend": "i2c", "i2c_bus": 3}, sim_time=True)
    assert opened == [3]
    ros.advance(1.0, step=0.01)  # scans at the start instant and every 10 ms; diagnostics at 0 s and 1 s
    assert ros.spin_until(lambda: len(seen["little"]) == 101 and len(diagnostics) == 2)
    ros.spin_for(0.1)
    assert {f: len(m) for f, m in seen.items()} == {"thumb": 101, "index": 101, "middle": 101,
                                                    "ring": 0, "little": 101}
    np.testing.assert_array_equal(seen["middle"][0].counts, values[2])
    np.testing.assert_allclose(seen["middle"][0].voltages, values[2] * 3.3 / 4096, rtol=1e-6)
    status = diag_by_name(diagnostics[-1])
    assert status["tactile_driver: ring"].level == DiagnosticStatus.STALE
    assert status["tactile_driver: hub"].level == DiagnosticStatus.WARN
    for finger in ("thumb", "index", "middle", "little"):
        assert status[f"tactile_driver: {finger}"].level == DiagnosticStatus.OK
    counters = {kv.key: kv.value for kv in status["tactile_driver: hub"].values}
    assert counters["ring_errors"] == str(3 * 101) and counters["ring_reads"] == "0"


def test_i2c_socket_reads_the_emulator_process_bus_once_it_serves(ros, node_cls, tmp_path):
    from prisma_tactile_driver.i2c_emulator import five_finger_bus
    from prisma_tactile_driver.i2c_socket import I2CSocketServer
    path = tmp_path / "i2c.sock"
    values = {ch: np.arange(9) * 300 + 7 * ch for ch in range(5)}
    ros.capture_logs()
    seen = {f: ros.collect(TaxelArray, f"/prisma/{f}/taxels") for f in FINGERS}
    diagnostics = ros.collect(DiagnosticArray, "/diagnostics")
    ros.node(node_cls, params={"backend": "i2c", "i2c_socket": str(path)}, sim_time=True)
    reason = f"cannot open I2C bus {path}: [Errno 2] No such file or directory"
    assert ros.wait_for_log(severity="error", contains=reason) == [reason]
    assert ros.spin_until(lambda: len(diagnostics) == 1)
    status = diag_by_name(diagnostics[0])["tactile_driver: hub"]
    assert status.level == DiagnosticStatus.ERROR and status.message.endswith(reason)
    assert status.hardware_id == f"i2c-socket:{path}/0x70"
    with I2CSocketServer(five_finger_bus(values), path):  # the emulator process comes up
        ros.advance(2.0, step=0.01)  # the bus is tried again 1 s after the failed open
        assert ros.spin_until(lambda: len(seen["little"]) == 101 and len(diagnostics) == 3)
        for ch, finger in enumerate(FINGERS):
            np.testing.assert_array_equal(seen[finger][0].counts, values[ch])
        assert diag_by_name(diagnostics[2])["tactile_driver: hub"].level == DiagnosticStatus.OK
    assert ros.logs(severity="error") == [reason]


def test_serial_backend_publishes_what_the_hub_streams(ros, node_cls, tmp_path):
    from prisma_tactile_driver.pty_hub import PtyHubPort
    port = PtyHubPort(tmp_path / "ttyHUB")
    port.open()
    try:
        index = ros.collect(TaxelArray, "/prisma/index/taxels")
        hands = ros.collect(HandTaxels, "/prisma/hand/taxels")
        node = ros.node(node_cls, params={"backend": "serial", "port": str(port.link_path),
                                          "fingers": ["index", "thumb"], "finger_channels": [0, 1]})
        assert ros.spin_until(lambda: node.hub.backend.counters().get("opens", 0) == 1)
        rng = np.random.default_rng(1)
        sent = [rng.integers(0, 4096, (5, 9)) for _ in range(10)]
        port.write(b"junk" + b"".join(encode_frame(i, c) for i, c in enumerate(sent)))
        assert ros.spin_until(lambda: len(index) == 10)
        assert [m.counts.tolist() for m in index] == [c[1].tolist() for c in sent]
        # the frames drained together travel together: every sample once, in the order read
        assert ros.spin_until(lambda: sum(len(h.samples) for h in hands) == 20)
        samples = [s for h in hands for s in h.samples]
        assert [s for s in samples if s.finger == "index"] == list(index)
        assert len(hands) < 10 and all(stamp_ns(h) == stamp_ns(h.samples[-1]) for h in hands)
    finally:
        port.close()


def test_hand_world_contact_source_is_fed_from_joint_states(ros, node_cls, monkeypatch):
    calls = []

    class FakeHandWorld:
        def __init__(self, world):
            self.world = world  # the node draws its object
            self.closure = 0.0

        def update_joints(self, names, positions, stamp_ns):
            calls.append((names, positions, stamp_ns))
            self.closure = dict(zip(names, positions)).get("fingers", 0.0)

        def contact(self, finger, stamp_ns):
            return PadContact(0.0, 0.0, 3.0) if finger == "index" and self.closure > 1.0 else None

    # the node module's own name for the contact source (imported at module level)
    monkeypatch.setattr(sys.modules[node_cls.__module__], "HandWorldContactSource", FakeHandWorld)
    index = ros.collect(TaxelArray, "/prisma/index/taxels")
    ros.node(node_cls, params={"contact_source": "hand_world"}, sim_time=True)
    ros.advance(0.1, step=0.01)
    assert ros.spin_until(lambda: len(index) == 11)  # the start instant and 10 more
    msg = JointState()
    msg.header.stamp.sec = 1_700_000_000
    msg.name = ["fingers", "thumb_flexion", "thumb_rotation"]
    msg.position = [2.0, 0.5, 0.1]
    ros.publish("/joint_states", msg)
    assert ros.spin_until(lambda: calls)
    ros.advance(0.1, step=0.01)
    assert ros.spin_until(lambda: len(index) == 21)
    assert calls == [(["fingers", "thumb_flexion", "thumb_rotation"], [2.0, 0.5, 0.1], 1_700_000_000 * 10**9)]
    assert index[5].voltages[4] < 0.6 and index[-1].voltages[4] > 1.5


def test_real_hand_world_source_runs_in_the_node(ros, node_cls):
    thumb = ros.collect(TaxelArray, "/prisma/thumb/taxels")
    ros.node(node_cls, params={"contact_source": "hand_world"}, sim_time=True)
    ros.advance(0.19, step=0.01)
    assert ros.spin_until(lambda: len(thumb) == 20)
    ros.spin_for(0.05)
    assert len(thumb) == 20


@pytest.mark.parametrize("sim_object, pressed", [("pinch_ball", True), ("none", False)])
def test_sim_object_names_what_the_hand_closes_on(ros, node_cls, sim_object, pressed):
    """The hand closed to fingers 5 rad, thumb 4.5 rad: 2 rad past the pinch ball's contacts (about
    1 N). With the ball its index and thumb pads are pressed; with sim_object none nothing touches them."""
    index, thumb = ros.collect(TaxelArray, "/prisma/index/taxels"), ros.collect(TaxelArray, "/prisma/thumb/taxels")
    ros.node(node_cls, params={"contact_source": "hand_world", "sim_object": sim_object}, sim_time=True)
    msg = JointState(name=["fingers", "thumb_flexion", "thumb_rotation"], position=[5.0, 4.5, 0.0])
    msg.header.stamp.sec = 1_700_000_000
    ros.publish("/joint_states", msg)
    ros.advance(0.1, step=0.01)
    assert ros.spin_until(lambda: len(index) >= 11 and len(thumb) >= 11)
    rest = np.mean(PadParams().rest_volts)
    for pad in (index, thumb):
        mean = float(np.mean(pad[-1].voltages))
        assert (mean > rest + 0.2) if pressed else abs(mean - rest) < 0.02, (sim_object, mean)


@pytest.mark.parametrize("sim_object, success, says", [
    ("pinch_ball", True, "pinch_ball re-placed at the thumb pad's middle"),
    ("none", False, "no object to put back: the hand is empty (object 'none'); start it with one: "
                    "sim_object:=pinch_ball|power_ball|lateral_card"),
])
def test_replace_object_answers_what_it_did_or_why_not(ros, node_cls, sim_object, success, says):
    from std_srvs.srv import Trigger

    ros.node(node_cls, params={"contact_source": "hand_world", "sim_object": sim_object}, sim_time=True)
    answer = ros.call(Trigger, "/tactile_driver/replace_object", Trigger.Request())
    assert answer.success is success and answer.message.startswith(says), answer.message


class FakeEmulatorControl:
    """An emulator's control socket at `path` that answers each request with the next of `replies`
    (None: accepts and never answers), recording the requests it decoded, in the wire format of
    prisma_common.control_socket."""

    def __init__(self, path, replies):
        import socket
        import threading

        self.requests, self._replies = [], list(replies)
        self._listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self._listener.bind(str(path))
        self._listener.listen(1)
        self._silent = []  # connections left unanswered, closed with the fake
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self):
        from prisma_common.control_socket import decode_request, encode_reply, read_line

        while self._replies:
            connection, _ = self._listener.accept()
            self.requests.append(decode_request(read_line(connection)))
            reply = self._replies.pop(0)
            if reply is None:
                self._silent.append(connection)
                continue
            with connection:
                connection.sendall(encode_reply(reply))

    def close(self):
        self._thread.join(timeout=5.0)
        for connection in self._silent:
            connection.close()
        self._listener.close()


def test_emulated_hand_forwards_replace_object_to_the_emulators_world(ros, node_cls, tmp_path):
    """hand.launch.py hardware:=emulated passes `emulator_control`: ~/replace_object (under the hand's
    namespace) asks the emulator's world through its control socket and answers with its words,
    success or refusal; nobody at the path, or an emulator that does not answer, is said so."""
    from std_srvs.srv import Trigger

    from prisma_common.control_socket import REPLACE_OBJECT

    path = tmp_path / "control.sock"
    put_back = "pinch_ball re-placed at the thumb pad's middle (thumb rotation +0.000 rad)"
    touched = ("the object cannot be re-placed while index, thumb touch it: open the hand first "
               "(GripperCommand position 0)")
    ros.node(node_cls, namespace="left", params={"emulator_control": str(path)})
    service = "/left/tactile_driver/replace_object"

    answer = ros.call(Trigger, service, Trigger.Request())
    nobody = (f"no emulated hand at {path} (No such file or directory): is the emulator this hand was launched "
              f"with running? (emulator_control {path})")
    assert (answer.success, answer.message) == (False, nobody)
    fake = FakeEmulatorControl(path, [{"ok": True, "message": put_back}, {"ok": False, "error": touched}, None])
    try:
        answer = ros.call(Trigger, service, Trigger.Request())
        assert (answer.success, answer.message) == (True, put_back)
        answer = ros.call(Trigger, service, Trigger.Request())
        assert (answer.success, answer.message) == (False, touched)
        answer = ros.call(Trigger, service, Trigger.Request())
        assert (answer.success, answer.message) == (False, f"the emulator at {path} did not answer within 1 s")
    finally:
        fake.close()
    assert fake.requests == [(REPLACE_OBJECT, {})] * 3


def test_no_replace_object_without_a_world(ros, node_cls):
    """The scripted pads (no world, no emulator) offer no ~/replace_object: nothing to put back."""
    ros.node(node_cls)
    ros.spin_for(0.5)
    assert "/tactile_driver/replace_object" not in {name for name, _ in ros.probe.get_service_names_and_types()}
