"""tactile_markers and tendon_stretch node parameters: defaults (= config/<node>.yaml), their descriptions and
ranges, and validation naming the bad parameter and value."""
from __future__ import annotations

from dataclasses import dataclass

from prisma_common.hand import FINGERS, TAXEL_PITCH_M
from prisma_common.parameters import Params, check_fingers, parameter
from prisma_hand_sim.hand_world import HandWorldParams


@dataclass
class TactileMarkersConfig(Params):
    fingers: list = parameter(list(FINGERS), "fingertip pads to draw",
                              rules=f"distinct names among {', '.join(FINGERS)}")
    rate_hz: float = parameter(30.0, "display rate: at most this many MarkerArrays per second", unit="Hz",
                               bounds=(0.0, 100.0), open_low=True, live=True)
    taxel_pitch: float = parameter(TAXEL_PITCH_M, "distance between taxel centres on a pad (the description's)",
                                   unit="m", bounds=(0.0, 0.02), open_low=True)
    cell_thickness: float = parameter(0.001, "height of the drawn taxel cells above the pad", unit="m",
                                      bounds=(0.0, 0.01), open_low=True, live=True)
    contact_force_n: float = parameter(0.1, "estimated normal force from which the contact point and the force "
                                       "arrow are drawn", unit="N", bounds=(0.0, 10.0), open_low=True, live=True)
    arrow_m_per_n: float = parameter(0.02, "force arrow length per newton", unit="m/N", bounds=(0.0, 1.0),
                                     open_low=True, live=True)
    arrow_max_length: float = parameter(0.06, "longest force arrow (longer ones are cut)", unit="m",
                                        bounds=(0.0, 1.0), open_low=True, live=True)

    def check_rules(self) -> None:
        check_fingers(self.fingers)


@dataclass
class TendonStretchConfig(Params):
    # robot_state_publisher draws at most 20 times a second (its publish_frequency): taking every motor
    # sample (100 Hz) and wrench to publish one in four cost 0.7 of a bare relay beside the control path
    publish_period: float = parameter(0.04, "display period: once per period the newest joint state and "
                                            "wrench are taken and one full joint state published; the "
                                            "samples between are dropped unread", unit="s",
                                      bounds=(0.0, 1.0), open_low=True)
    # the shipped hand's tendon (the simulator's model of it); a hand of its own is measured and set here
    tendon_stiffness_n_per_mm: float = parameter(HandWorldParams().tendon_stiffness_n_per_mm,
                                                 "stiffness of each finger's tendon referred to its fingertip: "
                                                 "the stretch is the pad's normal force over it",
                                                 unit="N/mm", bounds=(0.0, 100.0), open_low=True)
    force_timeout: float = parameter(0.2, "a pad's force estimate older than this (against the joint sample's "
                                          "stamp) counts as none: the finger is drawn as its motor says",
                                     unit="s", bounds=(0.0, 10.0), open_low=True, live=True)
