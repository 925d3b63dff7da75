"""The paper's scenarios (docs/manipulation.md) as ready closed loops (tests, bench, plots and the CLI).

Their names are the scenarios' names everywhere: prisma-sim, prisma-manip-scenarios, the hand
emulator's worlds (`prisma-hand-emulator --world`, `hand.launch.py hardware:=emulated sim_object:=`,
`prisma-hand-fault world`).

Each is a world to start from (prisma_hand_sim.scenario_worlds, which the hand emulator reads too)
and the goal a client sends the manipulation node, run through the node's own cores
(`closed_loop.ClosedLoop`); every setting not in the goal is the node's default configuration
(`ManipulationConfig`). The goals:
- horizontal: Manipulate horizontal at 20 rpm.
- vertical: Manipulate vertical at 10 rpm.
- disturbance: Manipulate hold at 20 rpm restores the left side after the push.
- pinch_grasp: Grasp pinch (60 rpm, 0.8 N / 1.0 N).
- lateral_grasp: Grasp lateral: the fingers close to the lateral fist by position, then the thumb
  flexes to 1 N.
- combined: Manipulate hold with use_force: the thumb restores 1 N while rotation restores the
  contact side.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from prisma_hand_sim.scenario_worlds import SCENARIO_NAMES, scenario_world

from .closed_loop import ClosedLoop, Trace
from .contact_monitor import DEFAULT_K
from .controllers import Controller
from .manipulation_core import GraspRequest, ManipulateRequest

if TYPE_CHECKING:
    from prisma_force_estimator.inference import ForceEstimator

__all__ = ["SCENARIO_NAMES", "Scenario", "ScenarioSpec", "build", "scenario_request"]  # the names, for the CLIs


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


def build(name: str, estimator: ForceEstimator | None = None, k: float = DEFAULT_K, seed: int = 0,
          rate_hz: float = 100.0, speed_rpm: float | None = None, observer=None) -> Scenario:
    """The scenario's closed loop: with `estimator` the force estimator's core turns taxels into
    the forces the manipulation core steers by, without it the world's pad forces do."""
    world = scenario_world(name)
    spec = _specs(k, speed_rpm)[name]
    loop = ClosedLoop(world, estimator, rate_hz=rate_hz, seed=seed, observer=observer)
    return Scenario(name, loop, spec.request, spec.duration_s, spec.settle_s)
