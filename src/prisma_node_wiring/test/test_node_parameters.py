"""node_parameters on real rclpy: a node's parameters declared from a config dataclass are described
from the specs (description and unit, range, constraints, read-only), checked at start with the
config's message, and the live ones change at run time through the same checks."""
from __future__ import annotations

import re
from dataclasses import dataclass

import pytest

from prisma_testing.ros_harness import require_ros

require_ros()

from rcl_interfaces.msg import ParameterType  # noqa: E402
from rclpy.node import Node  # noqa: E402

from prisma_common.parameters import ParameterError, Params, parameter  # noqa: E402
from prisma_node_wiring.node_parameters import accept_live_changes, declare_config  # noqa: E402


@dataclass
class DemoConfig(Params):
    backend: str = parameter("sim", "where samples come from", choices=("sim", "serial"))
    k: float = parameter(0.8, "threshold factor", bounds=(0.0, 1.5), open_low=True, live=True)
    timeout: float = parameter(0.1, "silence before stale", unit="s", bounds=(0.0, 1.0), open_low=True, live=True)
    band: float = parameter(0.05, "below the timeout", unit="s", bounds=(0.0, 1.0), live=True,
                            rules="below timeout")
    samples: int = parameter(10, "samples averaged", bounds=(1, 100))
    fingers: list = parameter(["thumb"], "pads read")

    def check_rules(self) -> None:
        if self.band >= self.timeout:
            raise ParameterError("band", self.band, f"must be below timeout {self.timeout}")


class DemoNode(Node):
    def __init__(self, **kwargs) -> None:
        super().__init__("demo_parameters", **kwargs)
        self.config = declare_config(self, DemoConfig)
        self.applied: list[DemoConfig] = []
        accept_live_changes(self, DemoConfig, self._reconfigure)

    def _reconfigure(self, config: DemoConfig) -> None:
        self.config = config
        self.applied.append(config)


def describe(node: Node) -> dict:
    names = [n for n in node.list_parameters([], 0).names if n in DemoConfig.parameter_specs()]
    return {d.name: d for d in node.describe_parameters(names)}


def test_every_parameter_is_described_from_its_spec(ros):
    described = describe(ros.node(DemoNode))
    assert set(described) == {"backend", "k", "timeout", "band", "samples", "fingers"}
    k, timeout, samples = described["k"], described["timeout"], described["samples"]
    assert (k.type, k.description, k.additional_constraints, k.read_only) == (
        ParameterType.PARAMETER_DOUBLE, "threshold factor", "in (0.0, 1.5]", False)
    assert [(r.from_value, r.to_value, r.step) for r in k.floating_point_range] == [(0.0, 1.5, 0.0)]
    assert timeout.description == "silence before stale [s]"
    assert [(r.from_value, r.to_value, r.step) for r in samples.integer_range] == [(1, 100, 1)]
    assert samples.read_only and samples.additional_constraints == ""
    backend = described["backend"]
    assert backend.additional_constraints == "one of: sim, serial" and backend.read_only
    assert not backend.floating_point_range and not backend.integer_range
    fingers = described["fingers"]
    assert fingers.description == "pads read" and not fingers.integer_range and fingers.read_only
    assert described["band"].additional_constraints == "below timeout"


@pytest.mark.parametrize("overrides, message", [
    ({"k": 2.0}, "invalid parameter 'k' = 2.0: must be > 0.0 and <= 1.5"),  # refused by rclpy's range check
    ({"k": 0.0}, "invalid parameter 'k' = 0.0: must be > 0.0 and <= 1.5"),  # the excluded end: the config's
    ({"samples": 0}, "invalid parameter 'samples' = 0: must be >= 1 and <= 100"),
    ({"k": 1}, "invalid parameter 'k' = 1: must be of type float, as its default 0.8"),
    ({"backend": "usb"}, "invalid parameter 'backend' = 'usb': expected one of sim|serial"),
    ({"band": 0.5}, "invalid parameter 'band' = 0.5: must be below timeout 0.1"),
])
def test_an_invalid_value_at_start_is_a_parameter_error_naming_it(ros, overrides, message):
    with pytest.raises(ParameterError) as info:
        ros.node(DemoNode, params=overrides)
    assert str(info.value) == message


def test_live_parameters_change_through_the_start_checks(ros, capfd):
    node = ros.node(DemoNode, params={"k": 0.5})
    assert node.config.k == 0.5
    (ok,) = ros.set_parameters("/demo_parameters", k=0.7)
    assert ok.successful and node.config.k == 0.7 and [c.k for c in node.applied] == [0.7]
    # the node's console line, read where rcutils writes it: in the README's full run the same line
    # never came back on /rosout to this process, after dozens of rclpy contexts in it (alone, it did)
    logged = capfd.readouterr().err
    assert re.search(r"INFO.*\[demo_parameters\]: parameter k = 0\.7\n", logged), logged
    (out_of_range,) = ros.set_parameters("/demo_parameters", k=2.0)
    assert (out_of_range.successful, out_of_range.reason) == (
        False, "Parameter k out of range Min: 0.0, Max: 1.5, value: 2.0")
    (excluded_end,) = ros.set_parameters("/demo_parameters", k=0.0)
    assert (excluded_end.successful, excluded_end.reason) == (
        False, "invalid parameter 'k' = 0.0: must be > 0.0 and <= 1.5")
    (read_only,) = ros.set_parameters("/demo_parameters", samples=20)
    assert (read_only.successful, read_only.reason) == (False, "Trying to set a read-only parameter: samples.")
    # a relation to another parameter: checked against the node's current values
    (relation,) = ros.set_parameters("/demo_parameters", band=0.2)
    assert (relation.successful, relation.reason) == (False, "invalid parameter 'band' = 0.2: must be below "
                                                             "timeout 0.1")
    assert node.get_parameter("band").value == 0.05 and len(node.applied) == 1
    # both at once (as `ros2 param load` or rqt_reconfigure's atomic set): checked together
    from rclpy.parameter import Parameter
    result = node.set_parameters_atomically([Parameter("timeout", value=0.5), Parameter("band", value=0.2)])
    assert result.successful and (node.config.timeout, node.config.band) == (0.5, 0.2)
    assert node.get_parameter("use_sim_time").value is False  # rclpy's own parameter is left alone
    assert node.set_parameters([Parameter("use_sim_time", value=False)])[0].successful
