"""tactile_driver parameters: one dataclass holding the defaults, validation naming the bad
parameter and value, and the backend factory. The node only copies ROS parameters in."""
from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, fields
from typing import Any

from prisma_common.hand import FINGERS
from prisma_common.parameters import ParameterError, check_fingers
from prisma_hand_sim.contact_source import ContactSource, ScriptedContactSource
from prisma_hand_sim.hand_world import OBJECTS

from .backend import HubBackend

BACKENDS = ("serial", "i2c", "sim")
CONTACT_SOURCES = ("scripted", "hand_world")


@dataclass
class TactileDriverConfig:
    backend: str = "sim"  # serial | i2c | sim
    fingers: list[str] = field(default_factory=lambda: list(FINGERS))  # fingers on this hub
    frame_id_format: str = "prisma_{finger}_pad"  # header.frame_id of each finger's TaxelArray
    rate_hz: float = 100.0  # I2C/sim scan rate (the serial hub sets its own rate in firmware)
    vref: float = 3.3  # ADC reference: V = vref * counts / 4096
    stale_timeout: float = 0.1  # s without a sample before a finger is reported stale
    diagnostics_period: float = 1.0  # s between /diagnostics messages
    # serial (Arduino hub)
    port: str = "/dev/ttyUSB1"  # the Dynamixel adapter (motor_driver) defaults to ttyUSB0
    baud: int = 1_000_000
    serial_poll_hz: float = 500.0  # how often the port is drained
    reconnect_backoff_initial: float = 0.05  # s, doubled per failed reopen
    reconnect_backoff_max: float = 2.0
    # direct I2C
    i2c_bus: int = 1  # /dev/i2c-<n>
    i2c_socket: str = ""  # the emulated bus of prisma-hand-emulator (a Unix socket); "" = /dev/i2c-<i2c_bus>
    mux_address: int = 0x70  # TCA9548A
    adc_address: int = 0x35  # MAX11617
    finger_channels: list[int] = field(default_factory=lambda: [0, 1, 2, 3, 4])  # per finger, in order
    i2c_retries: int = 2  # extra attempts per finger and scan after an OSError (NACK)
    # sim
    contact_source: str = "scripted"  # scripted | hand_world
    sim_object: str = "pinch_ball"  # hand_world: the object presented to the hand; "none" = empty hand
    sim_seed: int = 0

    @classmethod
    def from_parameters(cls, values: dict[str, Any]) -> TactileDriverConfig:
        known = {f.name for f in fields(cls)}
        # rclpy hands integer/double arrays over as array.array: store plain lists
        kwargs: dict[str, Any] = {k: (list(v) if hasattr(v, "__iter__") and not isinstance(v, (str, bytes)) else v)
                                  for k, v in values.items() if k in known}
        return cls(**kwargs).validate()

    def as_parameters(self) -> dict[str, Any]:
        return asdict(self)

    def validate(self) -> TactileDriverConfig:
        if self.backend not in BACKENDS:
            raise ParameterError("backend", self.backend, f"expected one of {'|'.join(BACKENDS)}")
        check_fingers(self.fingers)
        try:
            self.frame_id_format.format(finger="thumb")
        except (KeyError, IndexError, ValueError) as exc:
            raise ParameterError("frame_id_format", self.frame_id_format,
                                 f"a str.format pattern whose only field is {{finger}} ({exc})") from None
        for name in ("rate_hz", "vref", "stale_timeout", "diagnostics_period", "serial_poll_hz",
                     "reconnect_backoff_initial"):
            if not getattr(self, name) > 0:
                raise ParameterError(name, getattr(self, name), "must be > 0")
        if self.reconnect_backoff_max < self.reconnect_backoff_initial:
            raise ParameterError("reconnect_backoff_max", self.reconnect_backoff_max,
                                 f"must be >= reconnect_backoff_initial ({self.reconnect_backoff_initial})")
        if self.baud <= 0:
            raise ParameterError("baud", self.baud, "must be > 0")
        if self.i2c_retries < 0:
            raise ParameterError("i2c_retries", self.i2c_retries, "must be >= 0")
        if self.i2c_socket:
            self._check_i2c_socket()
        for name in ("mux_address", "adc_address"):
            if not 0x08 <= getattr(self, name) <= 0x77:
                raise ParameterError(name, getattr(self, name), "a 7-bit I2C address 0x08..0x77")
        if len(self.finger_channels) != len(self.fingers):
            raise ParameterError("finger_channels", self.finger_channels,
                                 f"one mux channel per finger ({len(self.fingers)})")
        for ch in self.finger_channels:
            if not 0 <= ch <= 7:
                raise ParameterError("finger_channels", self.finger_channels, f"channel {ch} is not 0..7")
        duplicates = sorted({ch for ch in self.finger_channels if self.finger_channels.count(ch) > 1})
        if duplicates:
            raise ParameterError("finger_channels", self.finger_channels, f"duplicate mux channel(s) {duplicates}")
        if self.contact_source not in CONTACT_SOURCES:
            raise ParameterError("contact_source", self.contact_source,
                                 f"expected one of {'|'.join(CONTACT_SOURCES)}")
        if self.sim_object not in OBJECTS:
            raise ParameterError("sim_object", self.sim_object, f"expected one of {'|'.join(OBJECTS)}")
        return self

    def _check_i2c_socket(self) -> None:
        from .i2c_socket import MAX_PATH_BYTES
        path = self.i2c_socket
        if not isinstance(path, str) or "\0" in path or not path.startswith("/"):
            raise ParameterError("i2c_socket", path, "the absolute path of the emulator's Unix socket (the node "
                                                     "may start in any directory), or empty for /dev/i2c-<i2c_bus>")
        size = len(os.fsencode(path))
        if size > MAX_PATH_BYTES:
            raise ParameterError("i2c_socket", path, f"a Unix socket path has at most {MAX_PATH_BYTES} bytes, "
                                                     f"this one {size}: choose a shorter path")

    def frame_id(self, finger: str) -> str:
        return self.frame_id_format.format(finger=finger)


def make_backend(config: TactileDriverConfig, contact_source: ContactSource | None = None) -> HubBackend:
    """The configured backend. For sim, `contact_source` defaults to the scripted cycle."""
    if config.backend == "serial":
        from .serial_backend import SerialHubBackend
        return SerialHubBackend(config.port, config.baud, read_timeout_s=0.0,
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
