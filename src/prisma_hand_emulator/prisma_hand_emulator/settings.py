"""What an emulated hand is made with: where its devices appear (EmulatorPaths), how it runs
(EmulatorSettings) and the worlds it can hold (WORLDS, world_for)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from prisma_common.control_socket import CONTROL_SOCKET_NAME
from prisma_hand_sim.hand_world import HandWorld
from prisma_hand_sim.scenario_worlds import SCENARIO_NAMES, scenario_world
from prisma_hand_sim.sim_objects import OBJECTS
from prisma_tactile_driver.pty_hub import ADAPTER_BUFFER_BYTES

# the fingertip pads reach the host through the Arduino hub (serial) or its own I2C bus (i2c)
TACTILE_LINKS = ("serial", "i2c")
# One vocabulary with the sim graph (hand.launch.py sim_object:=): an object presented to the open
# hand as sim:=true presents it (pinch_ball, the default: a foam ball let go once held; none: an empty
# hand), or a prisma-sim scenario's start, the hand posed and the object held
# (prisma_hand_sim.scenario_worlds.scenario_world).
WORLDS = tuple(OBJECTS) + SCENARIO_NAMES
DEFAULT_WORLD = "pinch_ball"
DEFAULT_DIR = Path("/tmp/prisma_hand_emulator")


def world_for(name: str) -> HandWorld:
    """The world `name` (one of WORLDS) at its start; ValueError naming the choices for another name."""
    if name in OBJECTS:
        return HandWorld(obj=name)
    if name not in SCENARIO_NAMES:
        raise ValueError(f"unknown world {name!r}; choose one of {', '.join(WORLDS)}")
    return scenario_world(name)


@dataclass(frozen=True)
class EmulatorPaths:
    """Where the emulated devices appear: the drivers' `port` / `i2c_socket` parameters name these."""

    root: Path

    @property
    def hub(self) -> Path:
        return self.root / "hub"

    @property
    def servos(self) -> Path:
        return self.root / "servos"

    @property
    def i2c(self) -> Path:
        return self.root / "i2c.sock"

    @property
    def control(self) -> Path:
        return self.root / CONTROL_SOCKET_NAME

    def tactile(self, link: str) -> Path:
        """Where the pads' link appears: the hub's pty or the I2C bus socket."""
        return self.hub if link == "serial" else self.i2c


@dataclass(frozen=True)
class EmulatorSettings:
    rate_hz: float = 100.0  # hub scans per second (the Arduino firmware's rate)
    world: str = DEFAULT_WORLD  # one of WORLDS
    seed: int = 0  # pad noise
    tactile_link: str = "serial"  # serial | i2c: how the pads reach the host (TACTILE_LINKS)
    directions: tuple[int, ...] = (1, 1, 1)  # as motor_driver's `directions`, per MOTOR_NAMES
    zero_ticks: tuple[int, ...] = (0, 0, 0)  # as motor_driver's `zero_ticks`
    # a USB-serial adapter buffers only so much for a host that does not read: frames beyond this
    # are lost at the adapter, as on the robot (and the emulator never blocks on its pty)
    hub_buffer_bytes: int = ADAPTER_BUFFER_BYTES
