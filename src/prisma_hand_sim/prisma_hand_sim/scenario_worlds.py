"""The worlds the paper's scenarios (docs/manipulation.md) start from: the object, the hand's pose and
the pushes that come during the run. The scenario's names are one vocabulary everywhere (prisma-sim,
prisma-manip-scenarios, the hand emulator's `--world`, `hand.launch.py hardware:=emulated sim_object:=`,
`prisma-hand-fault world`); the goal each scenario sends is the controller's part
(prisma_manipulation.scenarios). Here, below both, so that the emulator and the sim runner read the
worlds without the controller package.
- horizontal, vertical: the object pinched between thumb and index at 1 N.
- disturbance: the same, and at 0.5 s a push slips the object 4 mm toward the thumb pad's right side.
- combined: as disturbance, and the object slips to a narrower section (grasp force drops).
- pinch_grasp: the hand open, a foam ball presented on a stand.
- lateral_grasp: the hand open, a card against the side of the index.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

from .hand_world import Disturbance, HandWorld
from .sim_objects import OBJECTS, released

SCENARIO_NAMES = ("pinch_grasp", "lateral_grasp", "horizontal", "vertical", "disturbance", "combined")


def pinched_world(force_n: float = 1.0, disturbances: Sequence[Disturbance] = ()) -> HandWorld:
    """Object already held between thumb and index at force_n, contact centred on the thumb pad."""
    world = HandWorld(obj=released("pinch_ball"), disturbances=list(disturbances))
    world.set_positions(world.grasp_pose(force_n))
    return world


def scenario_world(name: str) -> HandWorld:
    """The world a scenario starts from: its object, pose and disturbances (times from the start);
    ValueError naming the scenarios for another name."""
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
