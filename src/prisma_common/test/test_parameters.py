"""Node parameter specs and the Params base: one spec per field gives the description, the range
the ROS descriptor advertises and the check validate() applies."""
from __future__ import annotations

import array
from dataclasses import dataclass

import pytest

from prisma_common.parameters import (
    ParameterError,
    ParameterSpec,
    Params,
    backoff_initial,
    backoff_max,
    check_backoff,
    parameter,
)


@dataclass
class DemoConfig(Params):
    mode: str = parameter("fast", "how it runs", choices=("fast", "slow"))
    gain: float = parameter(0.8, "threshold factor", bounds=(0.0, 1.5), open_low=True, live=True)
    period: float = parameter(0.1, "check period", unit="s", bounds=(0.0, 1.0), open_low=True)
    samples: int = parameter(10, "samples averaged", bounds=(1, 100))
    margin: float = parameter(0.5, "below the top", bounds=(0.0, 3.3), open_high=True, live=True)
    channels: list = parameter([0, 1], "one per finger", rules="distinct, 0..7")
    enabled: bool = parameter(True, "on or off")
    label: str = parameter("", "free text")

    def check_rules(self) -> None:
        if len(set(self.channels)) != len(self.channels):
            raise ParameterError("channels", self.channels, "distinct channels")


def test_specs_come_from_the_fields_in_order():
    specs = DemoConfig.parameter_specs()
    assert list(specs) == ["mode", "gain", "period", "samples", "margin", "channels", "enabled", "label"]
    assert specs["period"] == ParameterSpec("check period", "s", (0.0, 1.0), open_low=True)
    assert DemoConfig.live_parameters() == ["gain", "margin"]
    # list defaults are copied per instance
    a, b = DemoConfig(), DemoConfig()
    a.channels.append(2)
    assert b.channels == [0, 1]


def test_constraints_say_what_a_range_cannot():
    specs = DemoConfig.parameter_specs()
    assert specs["gain"].interval() == "(0.0, 1.5]" and specs["gain"].constraints() == "in (0.0, 1.5]"
    assert specs["margin"].constraints() == "in [0.0, 3.3)"
    assert specs["samples"].interval() == "[1, 100]" and specs["samples"].constraints() == ""
    assert specs["mode"].constraints() == "one of: fast, slow"
    assert specs["channels"].constraints() == "distinct, 0..7"


@pytest.mark.parametrize("values, message", [
    ({"gain": 0.0}, "invalid parameter 'gain' = 0.0: must be > 0.0 and <= 1.5"),
    ({"gain": 1.6}, "invalid parameter 'gain' = 1.6: must be > 0.0 and <= 1.5"),
    ({"gain": float("nan")}, "invalid parameter 'gain' = nan: must be a finite number"),
    ({"gain": "high"}, "invalid parameter 'gain' = 'high': must be a finite number"),
    ({"margin": 3.3}, "invalid parameter 'margin' = 3.3: must be >= 0.0 and < 3.3"),
    ({"samples": 0}, "invalid parameter 'samples' = 0: must be >= 1 and <= 100"),
    ({"samples": 2.5}, "invalid parameter 'samples' = 2.5: must be an integer"),
    ({"samples": True}, "invalid parameter 'samples' = True: must be an integer"),
    ({"mode": "medium"}, "invalid parameter 'mode' = 'medium': expected one of fast|slow"),
    ({"enabled": 1}, "invalid parameter 'enabled' = 1: must be true or false"),
    ({"label": 3}, "invalid parameter 'label' = 3: must be a string"),
    ({"channels": [1, 1]}, "invalid parameter 'channels' = [1, 1]: distinct channels"),
    ({"speed": 3.0}, "invalid parameter 'speed' = 3.0: not a parameter of DemoConfig"),
])
def test_validation_names_the_parameter_the_value_and_the_bounds(values, message):
    with pytest.raises(ParameterError) as info:
        DemoConfig.from_parameters(values)
    assert str(info.value) == message


def test_the_ends_of_a_range_and_ros_value_types():
    config = DemoConfig.from_parameters({"gain": 1.5, "margin": 0.0, "samples": 100, "period": 1,
                                         "channels": array.array("q", [3, 4])})
    assert (config.gain, config.margin, config.samples) == (1.5, 0.0, 100)
    assert config.period == 1.0 and isinstance(config.period, float)  # an integer for a float parameter
    assert config.channels == [3, 4]  # rclpy's array.array as a list
    assert config.as_parameters()["channels"] == [3, 4]


def test_a_field_without_a_spec_or_bounds_on_a_string_is_refused():
    @dataclass
    class Undescribed(Params):
        rate: float = 1.0

    with pytest.raises(TypeError, match="Undescribed.rate is declared without parameter"):
        Undescribed.parameter_specs()
    with pytest.raises(TypeError, match="only numbers have a range"):
        parameter("x", "a name", bounds=(0, 1))
    with pytest.raises(ValueError, match="the low end must be below the high end"):
        parameter(1.0, "a rate", bounds=(2.0, 1.0))


@dataclass
class ReopeningConfig(Params):
    reconnect_backoff_initial: float = backoff_initial(0.5, "bus")
    reconnect_backoff_max: float = backoff_max(8.0)

    def check_rules(self) -> None:
        check_backoff(self.reconnect_backoff_initial, self.reconnect_backoff_max)


def test_the_reconnect_backoff_pair_every_reopening_driver_declares():
    specs = ReopeningConfig.parameter_specs()
    assert specs["reconnect_backoff_initial"] == ParameterSpec(
        "wait before reopening a lost bus, doubled after each failure", "s", (0.0, 60.0), open_low=True)
    assert specs["reconnect_backoff_max"].rules == "at least reconnect_backoff_initial"
    assert ReopeningConfig.from_parameters({"reconnect_backoff_max": 0.5}).reconnect_backoff_max == 0.5
    with pytest.raises(ParameterError) as info:
        ReopeningConfig.from_parameters({"reconnect_backoff_max": 0.25})
    assert str(info.value) == ("invalid parameter 'reconnect_backoff_max' = 0.25: "
                               "must be >= reconnect_backoff_initial (0.5)")
