"""The paper's scenarios (docs/manipulation.md) as ready closed loops (tests, bench, plots and the CLI).

- horizontal: object pinched between thumb and index at 1 N; HorizontalController at 20 rpm.
- vertical: same start; VerticalController at 10 rpm.
- disturbance: same start; at 0.5 s an external push slips the object 4 mm toward the thumb pad's
  right side; HoldController at 20 rpm restores the left side.
- grasp: hand open, a foam ball presented on a stand; GraspController (pinch, 60 rpm, 0.8 N / 1.0 N).
- lateral: a card against the side of the index; the fingers close to the lateral fist by position,
  then the thumb flexes to 1 N (GraspController lateral preset).
- combined: pinch held with use_force; the object slips to a narrower section (grasp force drops)
  and is pushed sideways; the thumb restores 1 N while rotation restores the contact side.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable

from .closed_loop import ClosedLoop, ForceFn, Trace
from .contact_monitor import ContactMonitor
from .controllers import ControlLimits, Controller
from .grasp_controller import GraspController
from .hand_world import OBJECTS, Disturbance, HandWorld, released
from .motion_controllers import ForceKeeper, HoldController, HorizontalController, VerticalController
from .motor_bus import default_motors
from .sim_motors import SimMotorBus

DEFAULT_K = 0.8  # K of every scenario (the hold needs K > 0.6)


@dataclass
class Scenario:
    name: str
    loop: ClosedLoop
    controller: Controller
    duration_s: float
    settle_s: float = 0.3

    def run(self, progress: Callable[[str], None] | None = None) -> Trace:
        return self.loop.run(self.controller, self.duration_s, settle_s=self.settle_s, progress=progress)


def _loop(world: HandWorld, k: float, force_fn: ForceFn | None, seed: int, rate_hz: float) -> ClosedLoop:
    bus = SimMotorBus(default_motors(), initial_positions=world.positions)
    return ClosedLoop(world, bus, ContactMonitor(k), force_fn, rate_hz=rate_hz, seed=seed)


def pinched_world(force_n: float = 1.0, disturbances=()) -> HandWorld:
    """Object already held between thumb and index at force_n, contact centred on the thumb pad."""
    world = HandWorld(obj=released("pinch_ball"), disturbances=disturbances)
    world.set_positions(world.grasp_pose(force_n))
    return world


def scenario_world(name: str) -> HandWorld:
    """The world a scenario starts from: its object, pose and disturbances (times from the start)."""
    if name in ("horizontal", "vertical"):
        return pinched_world()
    if name == "disturbance":
        return pinched_world(disturbances=[Disturbance(0.5, 0.3, dx_mm=-4.0)])
    if name == "combined":
        return pinched_world(disturbances=[Disturbance(0.5, 0.3, dx_mm=-4.0, dwidth_mm=-6.0)])
    if name == "grasp":
        # presented on a stand that does not let go: each phase's force stays what it reached
        return HandWorld(obj=replace(OBJECTS["pinch_ball"], release_force_n=None, fixture_n_per_mm=5.0))
    if name == "lateral":
        # a card against the side of the index: the fingers close to the lateral fist by position
        return HandWorld(obj="lateral_card")
    raise ValueError(f"unknown scenario {name!r}; have {SCENARIO_NAMES}")


def build(name: str, force_fn: ForceFn | None = None, k: float = DEFAULT_K, seed: int = 0,
          rate_hz: float = 100.0, speed_rpm: float | None = None) -> Scenario:
    limits = ControlLimits(default_motors())
    world = scenario_world(name)
    loop = _loop(world, k, force_fn, seed, rate_hz)
    if name == "horizontal":
        return Scenario(name, loop, HorizontalController(limits, speed_rpm or 20.0), 10.0)
    if name == "vertical":
        return Scenario(name, loop, VerticalController(limits, speed_rpm or 10.0), 15.0)
    if name == "disturbance":
        return Scenario(name, loop, HoldController(limits, speed_rpm or 20.0, timeout_s=3.0), 4.0, 0.0)
    if name == "grasp":
        return Scenario(name, loop, GraspController(limits, "pinch", 0.8, 1.0, speed_rpm or 60.0), 10.0, 0.5)
    if name == "lateral":
        return Scenario(name, loop, GraspController(limits, "lateral", 0.8, 1.0, speed_rpm or 60.0), 10.0, 0.5)
    assert name == "combined"  # scenario_world refused every other name
    keeper = ForceKeeper(target_n=1.0, band_n=0.15, speed_rpm=20.0)
    return Scenario(name, loop, HoldController(limits, speed_rpm or 20.0, timeout_s=3.0, force_keeper=keeper),
                    4.0, 0.0)


SCENARIO_NAMES = ("horizontal", "vertical", "disturbance", "grasp", "lateral", "combined")
