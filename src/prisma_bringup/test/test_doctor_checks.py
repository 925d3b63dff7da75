"""prisma-doctor's checks on plain facts: a healthy emulated hand passes every line, and each bring-up
fault fails exactly its own line, with a fix (the others OK, or SKIP naming the failing line)."""
from __future__ import annotations

import dataclasses
import os

import pytest

from prisma_bringup.doctor_checks import run_checks
from prisma_bringup.doctor_facts import HandFacts, PortFacts, TaxelSample, counted_rate_hz, port_facts
from prisma_bringup.doctor_result import CheckResult, exit_status
from prisma_common.diagnostics import ERROR, OK, WARN, DiagnosticStatusData
from prisma_common.hand import FINGERS, MOTOR_NAMES

SERVOS, HUB = "/dev/ttyUSB0", "/dev/ttyUSB1"
BUNDLE = "/opt/prisma/share/prisma_bringup/config/models/cnn2"


def servo_values(motor_id: int, **changes: str) -> dict[str, str]:
    values = {"id": str(motor_id), "homed": "True", "hardware_error": "0", "model": "1020", "firmware": "46",
              "operating_mode": "velocity", "watchdog_ms": "100", "watchdog_fired": "False",
              "current_limit_ma": "1200"}
    return {**values, **changes}


def diagnostics(bus: tuple[int, str] = (OK, "ok"), servo: dict[str, dict[str, str]] | None = None,
                hub: tuple[int, str] = (OK, "all fingers streaming")) -> list[DiagnosticStatusData]:
    statuses = [DiagnosticStatusData("motor_driver: bus", bus[0], bus[1], SERVOS,
                                     {"backend": "dynamixel", "port": SERVOS, "baud": "1000000", "reads": "5000",
                                      "retries": "2"})]
    for motor_id, motor in enumerate(MOTOR_NAMES, 1):
        values = servo_values(motor_id, **(servo or {}).get(motor, {}))
        level = ERROR if values["hardware_error"] != "0" else OK
        statuses.append(DiagnosticStatusData(f"motor_driver: {motor}", level, "ok", f"{SERVOS}#{motor_id}", values))
    statuses.append(DiagnosticStatusData("tactile_driver: hub", hub[0], hub[1], f"{HUB}@1000000",
                                         {"frames": "5678", "port": HUB, "last_error": ""}))
    statuses += [DiagnosticStatusData(f"force_estimator: {f}", OK, "ok", BUNDLE, {"model_kind": "cnn2"})
                 for f in FINGERS]
    return statuses


def healthy(**changes) -> HandFacts:
    facts = HandFacts(
        namespace="", env={"ROS_DOMAIN_ID": "42"}, rtprio=(95, 99), rt_capable=False,
        nodes=["/tactile_driver", "/motor_driver", "/force_estimator", "/manipulation", "/robot_state_publisher"],
        motor_params={"backend": "dynamixel", "port": SERVOS, "baud": 1_000_000, "motor_names": list(MOTOR_NAMES),
                      "motor_ids": [1, 2, 3]},
        tactile_params={"backend": "serial", "port": HUB, "baud": 1_000_000, "fingers": list(FINGERS),
                        "vref": 3.3, "rate_hz": 100.0},
        force_params={"fingers": list(FINGERS), "model_bundle": BUNDLE},
        diagnostics=diagnostics(), taxels={f: TaxelSample(99, 1.0, 0.37, 0.51) for f in FINGERS},
        ports={"servos": PortFacts(SERVOS, True, True, "dialout", True, True, True),
               "hub": PortFacts(HUB, True, True, "dialout", True, True, True)},
        udev_installed={"99-prisma-hub.rules": "/etc/udev/rules.d/99-prisma-hub.rules"})
    return dataclasses.replace(facts, **changes)


def by_name(results: list[CheckResult]) -> dict[str, CheckResult]:
    return {r.name: r for r in results}


def failing(facts: HandFacts) -> dict[str, CheckResult]:
    results = run_checks(facts)
    bad = {r.name: r for r in results if r.status == "FAIL"}
    for r in bad.values():
        assert r.fix, f"{r.line()}: a failure without a fix"
    assert exit_status(results) == (1 if bad else 0)
    return bad


def test_healthy_hand_passes_every_line():
    results = run_checks(healthy())
    assert [r.status for r in results] == ["OK"] * len(results), "\n".join(r.line() for r in results)
    assert exit_status(results) == 0
    lines = by_name(results)
    assert len(results) == 1 + 4 + 1 + 1 + 2 + 1 + 5 + 1 + 3 + 1
    assert lines["servo fingers"].line() == ("OK servo fingers: id 1, XM430-W350, firmware 46, 1000000 baud, "
                                              "velocity mode, watchdog 100 ms, homed, no hardware error")
    assert lines["fingertip thumb"].line() == "OK fingertip thumb: 99 Hz, 0.37-0.51 V"
    assert lines["ros domain"].found == "ROS_DOMAIN_ID 42, discovery SUBNET, 5 node(s) seen"
    assert lines["motor bus"].found == f"dynamixel, {SERVOS} at 1000000 baud, 5000 reads, 2 retries"


def test_nothing_running_says_so_in_one_line():
    facts = healthy(nodes=[], motor_params=None, tactile_params=None, force_params=None, diagnostics=[], taxels={},
                    ports={})
    results = run_checks(facts)
    assert [r.line() for r in results] == [
        "FAIL hand: no hand running in the root namespace (ROS_DOMAIN_ID 42, discovery SUBNET, 0 node(s) seen) -> "
        "start the hand (ros2 launch prisma_bringup hand.launch.py), or run the doctor with the ROS_DOMAIN_ID of "
        "the shell that launched it (this one: 42)"]
    assert exit_status(results) == 1
    # other nodes of the domain, none of the hand's: still the one line
    assert [r.name for r in run_checks(dataclasses.replace(facts, nodes=["/rviz2", "/glove_driver"]))] == ["hand"]


def test_no_hand_in_the_namespace_names_where_one_runs():
    left = ["/left/tactile_driver", "/left/motor_driver", "/left/force_estimator", "/left/manipulation"]
    (line,) = run_checks(healthy(nodes=left, motor_params=None, tactile_params=None, force_params=None))
    assert line.found == ("no hand running in the root namespace (ROS_DOMAIN_ID 42, discovery SUBNET, 4 node(s) "
                          "seen); a hand runs in /left: --namespace left")
    (line,) = run_checks(healthy(namespace="right", nodes=["/tactile_driver", "/motor_driver"]))
    assert line.found.endswith("; a hand runs in /: no --namespace")
    assert "hand.launch.py namespace:=right" in line.fix


def test_nothing_running_in_a_bad_ros_environment_fails_the_environment_only():
    (line,) = run_checks(healthy(nodes=[], env={"ROS_DOMAIN_ID": "abc"}))
    assert line.line() == ("FAIL ros domain: ROS_DOMAIN_ID='abc' is not a number -> export ROS_DOMAIN_ID=<0-101>, "
                           "the same in every shell of the hand")


def test_two_publishers_on_a_taxel_topic_fail_its_fingertip_line_naming_them():
    # a second hand's tactile_driver beside the first: both publish every finger's topic, their
    # counters mixed (the rate came out negative before) and the udev rule is not the fix
    two = {f: ["/tactile_driver", "/tactile_driver"] for f in FINGERS}
    mixed = TaxelSample(198, 1.0, 0.37, 0.51, published_hz=None)
    bad = failing(healthy(taxel_publishers=two, taxels={f: mixed for f in FINGERS},
                          nodes=[*healthy().nodes, "/tactile_driver"]))
    assert set(bad) == {"node tactile_driver", *(f"fingertip {f}" for f in FINGERS)}
    assert bad["fingertip thumb"].line() == (
        "FAIL fingertip thumb: two publishers on /prisma/thumb/taxels: /tactile_driver, /tactile_driver -> stop the "
        "extra one (a second launch of the hand, or a node started by hand: `ros2 topic info -v "
        "/prisma/thumb/taxels`); a second hand needs its own namespace:=")
    assert "udev" not in bad["fingertip thumb"].line()
    # a recorder or a bag played beside the driver, under another name: three publishers
    three = {**{f: ["/tactile_driver"] for f in FINGERS}, "ring": ["/tactile_driver", "/player", "/x/pub"]}
    assert list(failing(healthy(taxel_publishers=three))) == ["fingertip ring"]
    # one publisher: the line as before
    assert failing(healthy(taxel_publishers={f: ["/tactile_driver"] for f in FINGERS})) == {}


def test_duplicate_manipulation_node_fails_its_line():
    bad = failing(healthy(nodes=["/tactile_driver", "/motor_driver", "/force_estimator", "/manipulation",
                                 "/manipulation"]))
    assert list(bad) == ["node manipulation"]
    assert bad["node manipulation"].found.startswith("2 nodes named /manipulation")


def test_namespace_finds_the_hand_there_and_names_the_one_elsewhere():
    nodes = ["/left/tactile_driver", "/left/motor_driver", "/left/force_estimator", "/left/manipulation"]
    assert failing(healthy(namespace="left", nodes=nodes)) == {}
    # part of a hand here, its motor driver elsewhere: the node's own line names where it runs
    bad = failing(healthy(namespace="", nodes=["/tactile_driver", "/force_estimator", "/manipulation",
                                               "/left/motor_driver"]))
    assert bad["node motor_driver"].found == "/motor_driver not running (running as /left/motor_driver: --namespace)"


def test_hub_unplugged_fails_the_hub_line_only():
    facts = healthy(diagnostics=diagnostics(hub=(ERROR, "stale: thumb, index, middle, ring, little; serial port "
                                                        f"{HUB} lost: [Errno 5] Input/output error")),
                    taxels={f: TaxelSample(0, 1.0) for f in FINGERS},
                    ports={**healthy().ports, "hub": PortFacts(HUB, False)})
    bad = failing(facts)
    assert list(bad) == ["hub"]
    assert "plug the hub's USB cable in" in bad["hub"].fix
    lines = by_name(run_checks(facts))
    assert lines["fingertip index"].line() == "SKIP fingertip index: not checked: the hub link is down (see hub)"
    assert lines["port hub"].status == "SKIP"


@pytest.mark.parametrize("motor, motor_id", [("fingers", 1), ("thumb_flexion", 2)])
def test_servo_not_answering_fails_its_line(motor, motor_id):
    reason = f"disconnected: ping {motor} (id {motor_id}): [TxRxResult] There is no status packet! after 4 attempts"
    bad = failing(healthy(diagnostics=diagnostics(bus=(ERROR, reason))))
    assert list(bad) == [f"servo {motor}"]
    assert bad[f"servo {motor}"].found.startswith(f"id {motor_id} does not answer at 1000000 baud (ping {motor}")
    assert f"set its ID to {motor_id} and its baud to 1000000" in bad[f"servo {motor}"].fix
    lines = by_name(run_checks(healthy(diagnostics=diagnostics(bus=(ERROR, reason)))))
    assert lines["motor bus"].status == "SKIP"
    assert {lines[f"servo {m}"].status for m in MOTOR_NAMES if m != motor} == {"SKIP"}


def test_wrong_baud_fails_the_first_servos_line_with_the_baud_in_the_fix():
    """At a baud the servos do not use, the first ping (fingers, id 1) gets no answer."""
    reason = "disconnected: ping fingers (id 1): [TxRxResult] There is no status packet! after 4 attempts"
    facts = healthy(diagnostics=diagnostics(bus=(ERROR, reason)),
                    motor_params={**healthy().motor_params, "baud": 57600})  # type: ignore[dict-item]
    bad = failing(facts)
    assert list(bad) == ["servo fingers"]
    assert "does not answer at 57600 baud" in bad["servo fingers"].found
    assert "motor_driver's motor_ids/baud" in bad["servo fingers"].fix


def test_a_bus_error_naming_no_servo_fails_the_bus_line():
    bad = failing(healthy(diagnostics=diagnostics(bus=(ERROR, "disconnected: sync read: [TxRxResult] There is no "
                                                              "status packet! after 4 attempts"))))
    assert list(bad) == ["motor bus"]
    assert "every servo must answer at 1000000 baud" in bad["motor bus"].fix


def test_hardware_error_fails_its_servo_line():
    bad = failing(healthy(diagnostics=diagnostics(servo={"thumb_rotation": {"hardware_error": "32"}})))
    assert list(bad) == ["servo thumb_rotation"]
    assert bad["servo thumb_rotation"].found == "hardware error bit 5 overload"
    assert "power-cycle the servo" in bad["servo thumb_rotation"].fix


def test_unhomed_servo_fails_with_the_home_action():
    bad = failing(healthy(namespace="left", nodes=["/left/" + n for n in ("tactile_driver", "motor_driver",
                                                                          "force_estimator", "manipulation")],
                          diagnostics=diagnostics(servo={"fingers": {"homed": "False"}})))
    assert list(bad) == ["servo fingers"]
    assert bad["servo fingers"].fix == ('home it: ros2 action send_goal /left/prisma/motors/home '
                                        'prisma_msgs/action/HomeMotors "{motors: [fingers]}"')


@pytest.mark.parametrize("changes, found", [
    ({"watchdog_ms": "0"}, "Bus Watchdog off"),
    ({"watchdog_fired": "True"}, "its Bus Watchdog fired"),
    ({"firmware": "37"}, "firmware 37: the Bus Watchdog needs 38 or later"),
    ({"model": "1060"}, "model 1060 at id 2"),
    ({"operating_mode": "pwm"}, "operating mode pwm"),
])
def test_servo_settings_fail_its_line(changes, found):
    bad = failing(healthy(diagnostics=diagnostics(servo={"thumb_flexion": changes})))
    assert list(bad) == ["servo thumb_flexion"]
    assert bad["servo thumb_flexion"].found.startswith(found)


def test_a_driver_without_the_bring_up_values_warns():
    """Today's driver (before the bring-up diagnostics) reports only the id: advisory, not a failure."""
    statuses = [s if not s.name.startswith("motor_driver: ") or s.name.endswith("bus")
                else dataclasses.replace(s, values={"id": s.values["id"]}) for s in diagnostics()]
    results = by_name(run_checks(healthy(diagnostics=statuses)))
    assert results["servo fingers"].status == "WARN"
    assert results["servo fingers"].found == ("id 1, 1000000 baud; not reported by this motor driver: model, "
                                              "firmware, operating_mode, watchdog_ms, homed, hardware_error")


def test_port_without_write_permission_fails_its_port_line():
    ports = {**healthy().ports, "servos": PortFacts(SERVOS, True, False, "dialout", False, False, True)}
    bad = failing(healthy(ports=ports))
    assert list(bad) == ["port servos"]
    assert bad["port servos"].fix == "sudo usermod -aG dialout $USER, then log out and in"
    ports["servos"] = PortFacts(SERVOS, True, False, "dialout", False, True, True)
    assert "(already listed: log out and in again)" in failing(healthy(ports=ports))["port servos"].found
    ports["servos"] = PortFacts(SERVOS, True, False, "dialout", True, True, True)
    assert "sudo chmod g+rw" in failing(healthy(ports=ports))["port servos"].fix


def test_servo_port_absent_fails_the_port_line_and_skips_the_bus():
    reason = f"disconnected: cannot open Dynamixel port {SERVOS}: [Errno 2] No such file or directory"
    facts = healthy(diagnostics=diagnostics(bus=(ERROR, reason)),
                    ports={**healthy().ports, "servos": PortFacts(SERVOS, False)})
    bad = failing(facts)
    assert list(bad) == ["port servos"]
    assert by_name(run_checks(facts))["motor bus"].status == "SKIP"


def test_realtime_limit_too_low_fails_with_the_limits_fix():
    bad = failing(healthy(rtprio=(0, 0)))
    assert list(bad) == ["realtime"]
    assert " - rtprio 20` to /etc/security/limits.conf" in bad["realtime"].fix
    assert "ulimit -r 20" in failing(healthy(rtprio=(0, 99)))["realtime"].found
    assert failing(healthy(rtprio=(0, 0), rt_capable=True)) == {}
    assert failing(healthy(rtprio=(-1, -1))) == {}  # unlimited


def test_udev_rule_missing_fails_only_for_ports_under_dev():
    bad = failing(healthy(udev_installed={}))
    assert list(bad) == ["udev rule"]
    assert "/etc/udev/rules.d/" in bad["udev rule"].fix
    emulated = healthy(udev_installed={}, motor_params={**healthy().motor_params, "port": "/tmp/hand/servos"},
                       tactile_params={**healthy().tactile_params, "port": "/tmp/hand/hub"},
                       ports={"servos": PortFacts("/tmp/hand/servos", True, True),
                              "hub": PortFacts("/tmp/hand/hub", True, True)})
    assert failing(emulated) == {}


@pytest.mark.parametrize("sample, found", [
    (TaxelSample(0, 1.0), "nothing on /prisma/ring/taxels in 1.0 s"),
    (TaxelSample(30, 1.0, 0.4, 0.5), "30 Hz on /prisma/ring/taxels, expected ~100 Hz"),
    (TaxelSample(100, 1.0, 0.0, 0.0), "100 Hz, 0.00-0.00 V: every taxel at 0 V"),
    (TaxelSample(100, 1.0, 3.29, 3.3), "100 Hz, 3.29-3.30 V: every taxel at vref 3.3 V (saturated)"),
])
def test_fingertip_not_streaming_or_out_of_range_fails_its_line(sample, found):
    bad = failing(healthy(taxels={**healthy().taxels, "ring": sample}))
    assert list(bad) == ["fingertip ring"]
    assert bad["fingertip ring"].found.startswith(found)


@pytest.mark.parametrize("env, found", [
    ({"ROS_DOMAIN_ID": "abc"}, "ROS_DOMAIN_ID='abc' is not a number"),
    ({"ROS_DOMAIN_ID": "250"}, "ROS_DOMAIN_ID=250 is outside 0-232"),
    ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "OFF"}, "ROS_AUTOMATIC_DISCOVERY_RANGE=OFF"),
])
def test_bad_ros_environment_fails_the_domain_line(env, found):
    bad = failing(healthy(env=env))
    assert list(bad) == ["ros domain"]
    assert bad["ros domain"].found.startswith(found)


def test_missing_bundle_diagnostics_fail_the_bundles_line():
    statuses = [s for s in diagnostics() if s.name != "force_estimator: little"]
    bad = failing(healthy(diagnostics=statuses))
    assert list(bad) == ["bundles"]
    assert bad["bundles"].found == "no /diagnostics from force_estimator for little"
    warn = [dataclasses.replace(s, level=WARN) if s.name == "force_estimator: index" else s for s in diagnostics()]
    assert by_name(run_checks(healthy(diagnostics=warn)))["bundles"].status == "WARN"


def test_line_format():
    assert CheckResult("hub", False, "down", "plug it in").line() == "FAIL hub: down -> plug it in"
    assert CheckResult("hub", True, "up").line() == "OK hub: up"


def test_port_facts_of_a_file_and_of_nothing(tmp_path):
    path = tmp_path / "port"
    path.write_text("")
    facts = port_facts(str(path))
    assert (facts.exists, facts.writable, facts.is_device) == (True, True, False)
    assert port_facts(str(tmp_path / "absent")) == PortFacts(str(tmp_path / "absent"), False)
    if os.geteuid() != 0:  # root writes whatever the mode says
        path.chmod(0o444)
        assert not port_facts(str(path)).writable


def test_fingertip_rate_is_the_drivers_own_when_its_counters_came():
    # a starved doctor took in 40 of the 100 messages a second the driver published: the driver is fine
    busy = TaxelSample(40, 1.0, 0.4, 0.5, published_hz=99.6)
    line = by_name(run_checks(healthy(taxels={**healthy().taxels, "ring": busy})))["fingertip ring"].line()
    assert line == "OK fingertip ring: 100 Hz, 0.40-0.50 V (this check took in 40 Hz of it: the computer is busy)"
    # the driver's own count falls behind: the line fails whatever arrived here
    behind = TaxelSample(100, 1.0, 0.4, 0.5, published_hz=31.0)
    bad = failing(healthy(taxels={**healthy().taxels, "ring": behind}))
    assert bad["fingertip ring"].found.startswith("31 Hz on /prisma/ring/taxels, expected ~100 Hz")


def test_the_drivers_rate_from_its_counters_and_none_from_two_drivers_counters():
    second = 1_000_000_000
    assert counted_rate_hz([(5 * second, 1000), (7 * second, 1200)]) == pytest.approx(100.0)
    assert counted_rate_hz([(5 * second, 1000)]) is None  # one report
    assert counted_rate_hz([(5 * second, 1000), (5 * second + second // 2, 1050)]) is None  # too close
    # a second hand's tactile_driver reports under the same name: its counter, far behind the
    # first's, came latest (the doctor printed -10026 Hz and blamed the udev rule)
    assert counted_rate_hz([(5 * second, 20_552), (7 * second, 500)]) is None
