"""tactile_driver parameter validation (the node applies it at start)."""
import array

import pytest

from prisma_tactile_driver.driver_config import DriverConfig, ParameterError, make_backend
from prisma_tactile_driver.sim_backend import SimHubBackend


def test_defaults_are_valid_and_arrays_become_lists():
    config = DriverConfig.from_parameters({"finger_channels": array.array("q", [4, 3, 2, 1, 0])})
    assert config.finger_channels == [4, 3, 2, 1, 0]
    assert config.frame_id("ring") == "prisma_ring_pad"
    assert isinstance(make_backend(DriverConfig()), SimHubBackend)


@pytest.mark.parametrize("values, message", [
    ({"backend": "usb"}, "invalid parameter 'backend' = 'usb': expected one of serial|i2c|sim"),
    ({"vref": 0.0}, "invalid parameter 'vref' = 0.0: must be > 0"),
    ({"finger_channels": [0, 1, 1, 3, 4]}, "'finger_channels' = [0, 1, 1, 3, 4]: duplicate mux channel(s) [1]"),
    ({"finger_channels": [0, 1, 2]}, "'finger_channels' = [0, 1, 2]: one mux channel per finger (5)"),
    ({"finger_channels": [0, 1, 2, 3, 9]}, "channel 9 is not 0..7"),
    ({"fingers": ["thumb", "pinky"], "finger_channels": [0, 1]}, "'pinky' is not one of"),
    ({"fingers": ["thumb", "thumb"], "finger_channels": [0, 1]}, "each finger at most once"),
    ({"mux_address": 0x80}, "'mux_address' = 128"),
    ({"rate_hz": -1.0}, "'rate_hz' = -1.0"),
    ({"tare_samples": 0}, "'tare_samples' = 0"),
    ({"reconnect_backoff_max": 0.01}, "must be >= reconnect_backoff_initial"),
    ({"frame_id_format": "{hand}_pad"}, "'frame_id_format'"),
    ({"contact_source": "glove"}, "expected one of scripted|hand_world"),
])
def test_bad_values_are_named(values, message):
    with pytest.raises(ParameterError) as info:
        DriverConfig.from_parameters(values)
    assert message in str(info.value)
