"""tactile_driver parameter validation (the node applies it at start)."""
import array

import numpy as np
import pytest

from prisma_common.parameters import ParameterError
from prisma_tactile_driver.i2c_emulator import five_finger_bus
from prisma_tactile_driver.i2c_socket import I2CSocketServer, SocketSMBus
from prisma_tactile_driver.node_config import TactileDriverConfig, make_backend
from prisma_tactile_driver.sim_backend import SimHubBackend


def test_defaults_are_valid_and_arrays_become_lists():
    config = TactileDriverConfig.from_parameters({"finger_channels": array.array("q", [4, 3, 2, 1, 0])})
    assert config.finger_channels == [4, 3, 2, 1, 0]
    assert config.frame_id("ring") == "prisma_ring_pad"
    assert isinstance(make_backend(TactileDriverConfig()), SimHubBackend)


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
    ({"sim_object": "cup"}, "'sim_object' = 'cup': expected one of pinch_ball|power_ball|lateral_card|none"),
    ({"reconnect_backoff_max": 0.01}, "must be >= reconnect_backoff_initial"),
    ({"frame_id_format": "{hand}_pad"}, "'frame_id_format'"),
    ({"contact_source": "glove"}, "expected one of scripted|hand_world"),
    ({"i2c_socket": "i2c.sock"}, "'i2c_socket' = 'i2c.sock': the absolute path of the emulator's Unix socket"),
    ({"i2c_socket": "/" + "s" * 107}, "a Unix socket path has at most 107 bytes, this one 108"),
    ({"backend": "serial", "emulator_control": "control.sock"},
     "'emulator_control' = 'control.sock': the absolute path of the emulator's control socket "
     "(<emulator_dir>/control.sock)"),
    ({"backend": "serial", "emulator_control": "/" + "c" * 107}, "at most 107 bytes, this one 108"),
    ({"contact_source": "hand_world", "emulator_control": "/tmp/e/control.sock"},
     "'emulator_control' = '/tmp/e/control.sock': the simulated hand (contact_source hand_world) has its own world"),
])
def test_bad_values_are_named(values, message):
    with pytest.raises(ParameterError) as info:
        TactileDriverConfig.from_parameters(values)
    assert message in str(info.value)


def test_i2c_socket_makes_the_i2c_backend_read_the_emulator_process(tmp_path):
    path = tmp_path / "i2c.sock"
    config = TactileDriverConfig.from_parameters({"backend": "i2c", "i2c_socket": str(path),
                                                  "fingers": ["ring", "thumb"], "finger_channels": [3, 0]})
    backend = make_backend(config)
    try:
        assert backend.bus_name == str(path)
        assert backend.link_status().error == f"cannot open I2C bus {path}: [Errno 2] No such file or directory"
        values = {ch: np.arange(9) * 300 + ch for ch in range(5)}
        with I2CSocketServer(five_finger_bus(values), path):
            [reading] = backend.read(1_000_000_000)  # the bus is tried again once a second
            assert isinstance(backend._bus, SocketSMBus)
            assert {f: c.tolist() for f, c in reading.counts.items()} == {"ring": values[3].tolist(),
                                                                        "thumb": values[0].tolist()}
    finally:
        backend.close()
