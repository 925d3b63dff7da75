"""tactile_driver parameters: one dataclass holding the defaults and their specs (description, unit,
bounds, live or read-only), validation naming the bad parameter and value, and the backend factory.
The node only copies ROS parameters in.

Live: stale_timeout (the staleness /diagnostics reports, from its next message). Everything else
builds the link, the timers and the publishers at start.
"""
from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from prisma_common.control_socket import CONTROL_SOCKET_NAME
from prisma_common.hand import FINGERS
from prisma_common.parameters import (
    ParameterError,
    Params,
    backoff_initial,
    backoff_max,
    check_backoff,
    check_fingers,
    parameter,
)
from prisma_common.unix_socket import MAX_PATH_BYTES
from prisma_hand_sim.contact_source import ContactSource, ScriptedContactSource
from prisma_hand_sim.sim_objects import OBJECTS

from .backend import HubBackend

BACKENDS = ("serial", "i2c", "sim")
CONTACT_SOURCES = ("scripted", "hand_world")
I2C_ADDRESSES = (0x08, 0x77)  # 7-bit addresses outside the reserved ones


@dataclass
class TactileDriverConfig(Params):
    backend: str = parameter("sim", "fingertip hub link: serial (Arduino hub), i2c (the host reads the bus) or "
                                    "sim (pad model)", choices=BACKENDS)
    fingers: list[str] = parameter(list(FINGERS), "fingers on this hub",
                                   rules=f"distinct names of {', '.join(FINGERS)}")
    frame_id_format: str = parameter("prisma_{finger}_pad", "header.frame_id of each finger's TaxelArray",
                                     rules="a str.format pattern whose only field is {finger}")
    rate_hz: float = parameter(100.0, "I2C/sim scan rate (the serial hub sets its own rate in firmware)",
                               unit="Hz", bounds=(0.0, 1000.0), open_low=True)
    vref: float = parameter(3.3, "ADC reference: V = vref x counts / 4096", unit="V", bounds=(0.0, 5.0),
                            open_low=True)
    stale_timeout: float = parameter(0.1, "a finger without a sample this long is reported stale in /diagnostics",
                                     unit="s", bounds=(0.0, 10.0), open_low=True, live=True)
    diagnostics_period: float = parameter(1.0, "time between /diagnostics messages", unit="s", bounds=(0.0, 60.0),
                                          open_low=True)
    # serial (Arduino hub)
    port: str = parameter("/dev/ttyUSB1", "serial port of the Arduino hub (backend serial; the Dynamixel adapter "
                                          "defaults to ttyUSB0)")
    baud: int = parameter(1_000_000, "serial baud rate of the hub", unit="baud", bounds=(1, 4_000_000))
    serial_poll_hz: float = parameter(500.0, "the driver reads the hub's bytes as they come; it looks again this "
                                             "often when none come, and reopens a lost port at most this often",
                                      unit="Hz", bounds=(0.0, 10_000.0), open_low=True)
    reconnect_backoff_initial: float = backoff_initial(0.05, "port")
    reconnect_backoff_max: float = backoff_max(2.0)
    # direct I2C
    i2c_bus: int = parameter(1, "I2C bus number: /dev/i2c-<i2c_bus> (backend i2c)", bounds=(0, 255))
    i2c_socket: str = parameter("", "absolute path of prisma-hand-emulator's I2C bus socket; '' = "
                                    "/dev/i2c-<i2c_bus>")
    mux_address: int = parameter(0x70, "7-bit address of the TCA9548A mux", bounds=I2C_ADDRESSES)
    adc_address: int = parameter(0x35, "7-bit address of each pad's MAX11617 ADC", bounds=I2C_ADDRESSES)
    finger_channels: list[int] = parameter([0, 1, 2, 3, 4], "mux channel of each finger",
                                           rules="one per finger, in the order of fingers; distinct, 0..7")
    i2c_retries: int = parameter(2, "extra attempts per finger and scan after an I2C error (NACK)",
                                 bounds=(0, 10))
    # sim
    contact_source: str = parameter("scripted", "sim contacts: scripted (press/slide/roll/release cycle) or "
                                                "hand_world (from /joint_states)", choices=CONTACT_SOURCES)
    sim_object: str = parameter("pinch_ball", "hand_world: the object presented to the hand; none = an empty hand",
                                choices=tuple(OBJECTS))
    sim_seed: int = parameter(0, "seed of the simulated pads' noise", bounds=(0, 2**31 - 1))
    object_frame_id: str = parameter("prisma_hand_base", "hand_world: the frame of the object's marker "
                                                         "(prisma/sim/object), the hand's base with its frame prefix")
    # the emulated hand (hand.launch.py hardware:=emulated): its world is the emulator's
    emulator_control: str = parameter("", "absolute path of prisma-hand-emulator's control socket: ~/replace_object "
                                          "puts the emulator's object back ('' = no emulator)")

    def check_rules(self) -> None:
        check_fingers(self.fingers)
        try:
            self.frame_id_format.format(finger="thumb")
        except (KeyError, IndexError, ValueError) as exc:
            raise ParameterError("frame_id_format", self.frame_id_format,
                                 f"a str.format pattern whose only field is {{finger}} ({exc})") from None
        check_backoff(self.reconnect_backoff_initial, self.reconnect_backoff_max)
        if self.i2c_socket:
            _check_socket_path("i2c_socket", self.i2c_socket, "the absolute path of the emulator's Unix socket (the "
                               "node may start in any directory), or empty for /dev/i2c-<i2c_bus>")
        if self.emulator_control:
            _check_socket_path("emulator_control", self.emulator_control, "the absolute path of the emulator's "
                               f"control socket (<emulator_dir>/{CONTROL_SOCKET_NAME}), or empty without an emulator")
        if self.emulator_control and self.backend == "sim" and self.contact_source == "hand_world":
            raise ParameterError("emulator_control", self.emulator_control,
                                 "the simulated hand (contact_source hand_world) has its own world: leave it empty, "
                                 "or use backend serial|i2c on the emulator's devices")
        if len(self.finger_channels) != len(self.fingers):
            raise ParameterError("finger_channels", self.finger_channels,
                                 f"one mux channel per finger ({len(self.fingers)})")
        for ch in self.finger_channels:
            if not 0 <= ch <= 7:
                raise ParameterError("finger_channels", self.finger_channels, f"channel {ch} is not 0..7")
        duplicates = sorted({ch for ch in self.finger_channels if self.finger_channels.count(ch) > 1})
        if duplicates:
            raise ParameterError("finger_channels", self.finger_channels, f"duplicate mux channel(s) {duplicates}")

    def frame_id(self, finger: str) -> str:
        return self.frame_id_format.format(finger=finger)


def _check_socket_path(name: str, path: Any, what: str) -> None:
    """A Unix socket path the node may open from any directory: absolute, and short enough."""
    if not isinstance(path, str) or "\0" in path or not path.startswith("/"):
        raise ParameterError(name, path, what)
    size = len(os.fsencode(path))
    if size > MAX_PATH_BYTES:
        raise ParameterError(name, path, f"a Unix socket path has at most {MAX_PATH_BYTES} bytes, "
                                         f"this one {size}: choose a shorter path")


def make_backend(config: TactileDriverConfig, contact_source: ContactSource | None = None) -> HubBackend:
    """The configured backend. For sim, `contact_source` defaults to the scripted cycle."""
    if config.backend == "serial":
        from .serial_backend import SerialHubBackend
        return SerialHubBackend(config.port, config.baud, read_timeout_s=1.0 / config.serial_poll_hz,
                                backoff_initial_s=config.reconnect_backoff_initial,
                                backoff_max_s=config.reconnect_backoff_max)
    if config.backend == "i2c":
        from .i2c_backend import I2CHubBackend
        bus: int | str = config.i2c_bus
        factory: Callable[[str], Any] | None = None
        if config.i2c_socket:
            from .i2c_socket import SocketSMBus
            bus, factory = config.i2c_socket, SocketSMBus
        return I2CHubBackend(bus, dict(zip(config.fingers, config.finger_channels)),
                             mux_address=config.mux_address, adc_address=config.adc_address,
                             retries=config.i2c_retries, bus_factory=factory)
    from .sim_backend import SimHubBackend
    return SimHubBackend(contact_source or ScriptedContactSource(), config.fingers, seed=config.sim_seed)
