"""prisma-doctor's look at the running hand: an rclpy node that gathers, for a few seconds, what
the checks (doctor_checks.py) judge: the graph's nodes, the drivers' parameters, /diagnostics and a
second of each fingertip's taxels. doctor.py (the command line) imports it once its arguments are
right, so that a mistyped option needs no ROS."""
from __future__ import annotations

import os
import time
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from prisma_msgs.msg import TaxelArray
from rcl_interfaces.srv import GetParameters
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import parameter_value_to_python
from rclpy.qos import qos_profile_sensor_data

from prisma_common.diagnostics import diagnostics_from_msg, of_namespace
from prisma_common.hand import FINGERS
from prisma_common.messages import ns_from_stamp

from .doctor_facts import (
    HAND_NODES,
    SAMPLE_SECONDS,
    HandFacts,
    TaxelSample,
    counted_rate_hz,
    node_path,
    port_facts,
    rt_capable,
    rtprio_limits,
    udev_installed,
)

MOTOR_PARAMS = ("backend", "port", "baud", "motor_names", "motor_ids")
TACTILE_PARAMS = ("backend", "port", "baud", "fingers", "rate_hz", "vref", "i2c_socket")
FORCE_PARAMS = ("fingers", "model_bundle")
DISCOVERY_SETTLE_S = 0.5  # after every hand node is seen: a duplicate is discovered about as soon
TACTILE_STATUS = "tactile_driver"  # its per-finger statuses are "tactile_driver: <finger>"


class Gatherer:
    """An rclpy node that collects the facts of one hand for `timeout` seconds at most."""

    def __init__(self, namespace: str, timeout: float) -> None:
        self.namespace = namespace.strip("/")
        self.deadline = time.monotonic() + timeout
        self.context = rclpy.Context()
        rclpy.init(context=self.context, args=[])
        self.node = rclpy.create_node(f"prisma_doctor_{os.getpid()}", context=self.context,
                                      start_parameter_services=False)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.diagnostics: dict[tuple[str, str], Any] = {}
        self.samples: dict[str, list[tuple[int, float, float]]] = {f: [] for f in FINGERS}
        self.sampling = False
        # finger -> (report stamp ns, the driver's sample count then): the first report and the latest
        self.counted: dict[str, list[tuple[int, int]]] = {}

        def on_diagnostics(msg: Any) -> None:
            # every hand publishes on /diagnostics; a namespaced hand's statuses carry its namespace
            stamp = ns_from_stamp(msg.header.stamp)
            for status in diagnostics_from_msg(msg):
                ours = of_namespace(status, self.namespace)
                if ours is not None:
                    self.diagnostics[(ours.name, ours.hardware_id)] = ours
                    self._note_count(ours, stamp)

        def on_taxels(finger: str):
            def take(msg: Any) -> None:
                if self.sampling:
                    voltages = list(msg.voltages)
                    stamp = ns_from_stamp(msg.header.stamp)
                    self.samples[finger].append((stamp, min(voltages), max(voltages)))
            return take

        self.node.create_subscription(DiagnosticArray, "/diagnostics", on_diagnostics, 50)
        for finger in FINGERS:
            self.node.create_subscription(TaxelArray, node_path(self.namespace, f"prisma/{finger}/taxels"),
                                          on_taxels(finger), qos_profile_sensor_data)

    def _note_count(self, status: Any, stamp_ns: int) -> None:
        finger = status.name.removeprefix(f"{TACTILE_STATUS}: ")
        if finger == status.name or finger not in FINGERS or not status.values.get("samples", "").isdigit():
            return
        report = (stamp_ns, int(status.values["samples"]))
        if finger in self.counted:
            self.counted[finger][1] = report
        else:
            self.counted[finger] = [report, report]

    def published_hz(self, finger: str) -> float | None:
        """The driver's publish rate for `finger` from its sample counter over the reports seen."""
        return counted_rate_hz(self.counted.get(finger, []))

    def left(self) -> float:
        return max(0.0, self.deadline - time.monotonic())

    def spin_for(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=min(0.05, max(0.0, end - time.monotonic())))

    def nodes(self) -> list[str]:
        """The graph's nodes but this one (`N node(s) seen` counts the domain's, not the doctor)."""
        return [node_path(ns, name) for name, ns in self.node.get_node_names_and_namespaces()
                if node_path(ns, name) != self.node.get_fully_qualified_name()]

    def wait_for_nodes(self) -> list[str]:
        """The graph once every hand node is seen (plus a moment for duplicates), or at the deadline
        less the time the other steps need."""
        wanted = {node_path(self.namespace, n) for n in HAND_NODES}
        budget = max(0.5, self.left() - SAMPLE_SECONDS - 1.0)
        end = time.monotonic() + budget
        while time.monotonic() < end:
            self.spin_for(0.1)
            if wanted <= set(self.nodes()):
                self.spin_for(min(DISCOVERY_SETTLE_S, max(0.0, end - time.monotonic())))
                break
        return self.nodes()

    def parameters(self, node: str, names: Sequence[str]) -> dict[str, Any] | None:
        """The node's parameters by name (None when it does not answer); unset ones are left out."""
        client = self.node.create_client(GetParameters, node_path(self.namespace, f"{node}/get_parameters"))
        try:
            if not client.wait_for_service(timeout_sec=min(2.0, max(0.1, self.left()))):
                return None
            future = client.call_async(GetParameters.Request(names=list(names)))
            end = time.monotonic() + max(0.5, min(3.0, self.left()))
            while not future.done() and time.monotonic() < end:
                self.executor.spin_once(timeout_sec=0.05)
            if not future.done() or future.result() is None:
                return None
            values = [parameter_value_to_python(v) for v in future.result().values]
            return {n: v for n, v in zip(names, values) if v is not None}
        finally:
            self.node.destroy_client(client)

    def sample_taxels(self, seconds: float) -> dict[str, TaxelSample]:
        for values in self.samples.values():
            values.clear()
        self.sampling = True
        start = time.monotonic()
        self.spin_for(seconds)
        self.sampling = False
        elapsed = time.monotonic() - start
        return {f: TaxelSample(len(v), _stamped_seconds(v, elapsed), min((lo for _, lo, _ in v), default=0.0),
                               max((hi for _, _, hi in v), default=0.0)) for f, v in self.samples.items()}

    def wait_for_diagnostics(self, names: Sequence[str], counted: Sequence[str] = ()) -> None:
        """Until every status in `names` has come, and every finger in `counted` has two reports of its
        sample counter far enough apart to give the driver's rate (or the deadline)."""
        while self.left() > 0 and not (all(any(n == name for n, _ in self.diagnostics) for name in names)
                                       and all(self.published_hz(f) is not None for f in counted)):
            self.spin_for(0.1)

    def publishers(self, finger: str) -> list[str]:
        """The nodes publishing `finger`'s taxel topic, fully qualified."""
        topic = node_path(self.namespace, f"prisma/{finger}/taxels")
        return [node_path(info.node_namespace, info.node_name)
                for info in self.node.get_publishers_info_by_topic(topic)]

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)


def _stamped_seconds(samples: Sequence[tuple[int, float, float]], elapsed: float) -> float:
    """The time the samples cover by their stamps (n samples span n - 1 periods): the driver's rate,
    not how fast this process, starting up on a busy computer, took them in."""
    stamps = sorted(stamp for stamp, _, _ in samples)
    if len(stamps) < 2 or stamps[-1] <= stamps[0]:
        return elapsed
    return (stamps[-1] - stamps[0]) * 1e-9 * len(stamps) / (len(stamps) - 1)


def gather(namespace: str, timeout: float) -> HandFacts:
    gatherer = Gatherer(namespace, timeout)
    try:
        nodes = gatherer.wait_for_nodes()
        motor = gatherer.parameters("motor_driver", MOTOR_PARAMS) \
            if node_path(namespace, "motor_driver") in nodes else None
        tactile = gatherer.parameters("tactile_driver", TACTILE_PARAMS) \
            if node_path(namespace, "tactile_driver") in nodes else None
        force = gatherer.parameters("force_estimator", FORCE_PARAMS) \
            if node_path(namespace, "force_estimator") in nodes else None
        taxels = gatherer.sample_taxels(SAMPLE_SECONDS) if tactile is not None else {}
        wanted = (["motor_driver: bus"] if motor is not None else []) \
            + (["tactile_driver: hub"] if tactile is not None else []) \
            + ([f"force_estimator: {f}" for f in force.get("fingers", FINGERS)] if force is not None else [])
        fingers = tactile.get("fingers", FINGERS) if tactile is not None else ()
        gatherer.wait_for_diagnostics(wanted, fingers)
        taxels = {f: replace(sample, published_hz=gatherer.published_hz(f)) for f, sample in taxels.items()}
        diagnostics = list(gatherer.diagnostics.values())  # this hand's only (on_diagnostics)
        publishers = {f: gatherer.publishers(f) for f in fingers}
    finally:
        gatherer.close()
    ports = {}
    if motor is not None and motor.get("backend") == "dynamixel":
        ports["servos"] = port_facts(str(motor.get("port", "")))
    if tactile is not None and tactile.get("backend") == "serial":
        ports["hub"] = port_facts(str(tactile.get("port", "")))
    return HandFacts(namespace=namespace.strip("/"), env=dict(os.environ), rtprio=rtprio_limits(),
                     rt_capable=rt_capable(), nodes=nodes, motor_params=motor, tactile_params=tactile,
                     force_params=force, diagnostics=diagnostics, taxels=taxels, taxel_publishers=publishers,
                     sample_seconds=SAMPLE_SECONDS,
                     ports=ports, udev_installed=udev_installed())

