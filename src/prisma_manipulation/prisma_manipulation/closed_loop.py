"""ROS-free closed loop: sim motors -> hand/world -> pad models -> contact monitor + forces ->
controller -> sim motors, one sample per period with explicit stamps.

Per sample at t_k: read the motors at t_k, move the world to those positions, sample every pad
(PadModel counts -> volts), evaluate Algorithm 1 for every finger, compute the normal forces with
`force_fn(voltages[5, 9]) -> N[5]` (the force estimator) or take the world's ground truth when
`force_fn` is None, step the controller, and apply its command at t_k. Everything is recorded in a
`Trace` so tests can recompute stop conditions independently of the controller.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from prisma_tactile_driver.pad_model import PadModel, PadParams
from prisma_tactile_driver.taxels import FINGERS, counts_to_voltages

from .contact_monitor import ContactMonitor
from .controllers import ControlInput, Controller, JointSample
from .hand_world import HandWorld
from .motor_bus import MOTOR_NAMES
from .sim_motors import SimMotorBus

ForceFn = Callable[[np.ndarray], np.ndarray]


def estimator_force_fn(estimator, axis: str = "fz") -> ForceFn:
    """Normal force per finger from a prisma_force_estimator ForceEstimator (+Fz presses the pad)."""
    column = list(estimator.axes).index(axis)

    def forces(voltages: np.ndarray) -> np.ndarray:
        return np.asarray(estimator.estimate(voltages), dtype=np.float64)[:, column]

    return forces


@dataclass
class Trace:
    period_ns: int
    stamps_ns: list[int] = field(default_factory=list)
    voltages: list[np.ndarray] = field(default_factory=list)  # [5, 9] per sample
    thresholds: list[np.ndarray] = field(default_factory=list)  # [5]
    lost_edges: list[dict[str, tuple[str, ...]]] = field(default_factory=list)
    forces_true: list[np.ndarray] = field(default_factory=list)  # [5]
    forces_used: list[np.ndarray] = field(default_factory=list)  # [5] what the controller saw
    positions: list[np.ndarray] = field(default_factory=list)  # [3] MOTOR_NAMES order
    commands: list[np.ndarray] = field(default_factory=list)  # [3] rpm in force after this sample
    contact_xy: list[np.ndarray] = field(default_factory=list)  # [5, 2] (nan = no contact)
    phases: list[str] = field(default_factory=list)
    done_index: int | None = None

    def array(self, name: str) -> np.ndarray:
        return np.asarray(getattr(self, name))

    def finger_voltages(self, finger: str) -> np.ndarray:
        return self.array("voltages")[:, FINGERS.index(finger), :]

    def force(self, finger: str, which: str = "true") -> np.ndarray:
        return self.array(f"forces_{which}")[:, FINGERS.index(finger)]

    def position(self, motor: str) -> np.ndarray:
        return self.array("positions")[:, MOTOR_NAMES.index(motor)]

    def index_of(self, stamp_ns: int) -> int:
        return self.stamps_ns.index(stamp_ns)


class ClosedLoop:
    def __init__(
        self,
        world: HandWorld,
        bus: SimMotorBus,
        monitor: ContactMonitor | None = None,
        force_fn: ForceFn | None = None,
        rate_hz: float = 100.0,
        pad_params: PadParams | None = None,
        seed: int = 0,
    ) -> None:
        self.world = world
        self.bus = bus
        self.monitor = monitor or ContactMonitor()
        self.force_fn = force_fn
        self.period_ns = int(round(1e9 / rate_hz))
        self.pads = {f: PadModel(pad_params, seed=seed + i) for i, f in enumerate(FINGERS)}

    def sample(self, stamp_ns: int):
        """One sensor sample of the whole hand at stamp_ns (advances motors and world)."""
        states = self.bus.read_state(stamp_ns)
        positions = {n: s.position_rad for n, s in states.items()}
        joints = JointSample(stamp_ns, positions, {n: s.velocity_rpm for n, s in states.items()},
                             {n: s.current_ma for n, s in states.items()})
        self.world.update_joints(positions, stamp_ns)
        self.bus.set_loads(self.world.motor_loads())
        volts = np.stack([counts_to_voltages(self.pads[f].sample(self.world.contact(f))) for f in FINGERS])
        evaluations = {f: self.monitor.evaluate(f, stamp_ns, volts[i]) for i, f in enumerate(FINGERS)}
        truth = np.array([self.world.state.forces[f] for f in FINGERS])
        used = truth if self.force_fn is None else np.asarray(self.force_fn(volts), dtype=np.float64)
        return joints, volts, evaluations, truth, used

    def run(self, controller: Controller, duration_s: float, start_ns: int = 0, settle_s: float = 0.0,
            progress: Callable[[str], None] | None = None) -> Trace:
        """Run until the controller is done (then `settle_s` more with the motors stopped) or
        duration_s has passed."""
        trace = Trace(self.period_ns)
        n_max = int(round(duration_s * 1e9 / self.period_ns))
        settle_left = int(round(settle_s * 1e9 / self.period_ns))
        joints0 = self.sample(start_ns)[0]
        out = controller.start(joints0)
        if out.command is not None:
            self.bus.set_velocities(out.command.velocities_rpm)
        phase = controller.phase
        for k in range(1, n_max + 1):
            t = start_ns + k * self.period_ns
            joints, volts, evaluations, truth, used = self.sample(t)
            if not controller.done:
                out = controller.step(ControlInput(t, evaluations, dict(zip(FINGERS, used.tolist())), joints))
                if out.command is not None:
                    self.bus.set_velocities(out.command.velocities_rpm)
                if controller.done and trace.done_index is None:
                    trace.done_index = len(trace.stamps_ns)
                if progress and controller.phase != phase:
                    progress(f"t={t * 1e-9:.2f}s phase {phase} -> {controller.phase}")
                phase = controller.phase
            else:
                settle_left -= 1
            trace.stamps_ns.append(t)
            trace.voltages.append(volts)
            trace.thresholds.append(np.array([evaluations[f].threshold for f in FINGERS]))
            trace.lost_edges.append({f: evaluations[f].lost_edges for f in FINGERS})
            trace.forces_true.append(truth)
            trace.forces_used.append(used)
            trace.positions.append(np.array([joints.positions[m] for m in MOTOR_NAMES]))
            trace.commands.append(np.array([controller.command.velocities_rpm[m] for m in MOTOR_NAMES]))
            xy = np.full((len(FINGERS), 2), np.nan)
            for i, f in enumerate(FINGERS):
                c = self.world.contact(f)
                if c is not None:
                    xy[i] = (c.x_mm, c.y_mm)
            trace.contact_xy.append(xy)
            trace.phases.append(controller.phase)
            if controller.done and settle_left <= 0:
                break
        return trace
