"""The paper's scenarios (docs/manipulation.md) as ready closed loops (tests, bench, plots and the CLI).

Their names are the scenarios' names everywhere: prisma-sim, prisma-manip-scenarios, the hand
emulator's worlds (`prisma-hand-emulator --world`, `hand.launch.py hardware:=emulated sim_object:=`,
`prisma-hand-fault world`).

Each is a world to start from and the goal a client sends the manipulation node, run through the
node's own cores (`closed_loop.ClosedLoop`); every setting not in the goal is the node's default
configuration (`ManipulationConfig`).
- horizontal: object pinched between thumb and index at 1 N; Manipulate horizontal at 20 rpm.
- vertical: same start; Manipulate vertical at 10 rpm.
- disturbance: same start; at 0.5 s an external push slips the object 4 mm toward the thumb pad's
  right side; Manipulate hold at 20 rpm restores the left side.
- pinch_grasp: hand open, a foam ball presented on a stand; Grasp pinch (60 rpm, 0.8 N / 1.0 N).
- lateral_grasp: a card against the side of the index; Grasp lateral: the fingers close to the
  lateral fist by position, then the thumb flexes to 1 N.
- combined: pinch held, Manipulate hold with use_force; the object slips to a narrower section
  (grasp force drops) and is pushed sideways; the thumb restores 1 N while rotation restores the
  contact side.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

from prisma_hand_sim.hand_world import Disturbance, HandWorld
from prisma_hand_sim.sim_objects import OBJECTS, released

from .closed_loop import ClosedLoop, Trace
from .contact_monitor import DEFAULT_K
from .controllers import Controller
from .manipulation_core import GraspRequest, ManipulateRequest

if TYPE_CHECKING:
    from prisma_force_estimator.inference import ForceEstimator

SCENARIO_NAMES = ("pinch_grasp", "lateral_grasp", "horizontal", "vertical", "disturbance", "combined")


@dataclass(frozen=True)
class ScenarioSpec:
    request: GraspRequest | ManipulateRequest
    duration_s: float
    settle_s: float  # run on this long after the goal has finished


def _specs(k: float, speed_rpm: float | None) -> dict[str, ScenarioSpec]:
    def manipulate(motion: str, speed: float, timeout_s: float, use_force: bool = False) -> ManipulateRequest:
        return ManipulateRequest(motion, speed_rpm or speed, k, use_force, timeout_s)

    def grasp(kind: str) -> GraspRequest:
        return GraspRequest(kind, 0.8, 1.0, speed_rpm or 60.0, 10.0)

    return {
        "horizontal": ScenarioSpec(manipulate("horizontal", 20.0, 10.0), 10.0, 0.3),
        "vertical": ScenarioSpec(manipulate("vertical", 10.0, 15.0), 15.0, 0.3),
        "disturbance": ScenarioSpec(manipulate("hold", 20.0, 3.0), 4.0, 0.0),
        "pinch_grasp": ScenarioSpec(grasp("pinch"), 10.0, 0.5),
        "lateral_grasp": ScenarioSpec(grasp("lateral"), 10.0, 0.5),
        "combined": ScenarioSpec(manipulate("hold", 20.0, 3.0, use_force=True), 4.0, 0.0),
    }


def scenario_request(name: str, k: float = DEFAULT_K,
                     speed_rpm: float | None = None) -> GraspRequest | ManipulateRequest:
    """The goal the scenario sends."""
    if name not in SCENARIO_NAMES:
        raise ValueError(f"unknown scenario {name!r}; have {SCENARIO_NAMES}")
    return _specs(k, speed_rpm)[name].request


@dataclass
class Scenario:
    name: str
    loop: ClosedLoop
    request: GraspRequest | ManipulateRequest
    duration_s: float
    settle_s: float = 0.3

    def run(self, progress: Callable[[str], None] | None = None) -> Trace:
        return self.loop.run(self.request, self.duration_s, settle_s=self.settle_s, progress=progress)

    @property
    def controller(self) -> Controller:
        """The controller the manipulation core ran the goal with (after `run`)."""
        if self.loop.controller is None:
            raise RuntimeError(f"scenario {self.name} has not run yet: its controller starts with the goal")
        return self.loop.controller


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
    if name == "pinch_grasp":
        # presented on a stand that does not let go: each phase's force stays what it reached
        return HandWorld(obj=replace(OBJECTS["pinch_ball"], release_force_n=None, fixture_n_per_mm=5.0))
    if name == "lateral_grasp":
        # a card against the side of the index: the fingers close to the lateral fist by position
        return HandWorld(obj="lateral_card")
    raise ValueError(f"unknown scenario {name!r}; have {SCENARIO_NAMES}")


def build(name: str, estimator: ForceEstimator | None = None, k: float = DEFAULT_K, seed: int = 0,
          rate_hz: float = 100.0, speed_rpm: float | None = None, observer=None) -> Scenario:
    """The scenario's closed loop: with `estimator` the force estimator's core turns taxels into
    the forces the manipulation core steers by, without it the world's pad forces do."""
    world = scenario_world(name)
    spec = _specs(k, speed_rpm)[name]
    loop = ClosedLoop(world, estimator, rate_hz=rate_hz, seed=seed, observer=observer)
    return Scenario(name, loop, spec.request, spec.duration_s, spec.settle_s)
