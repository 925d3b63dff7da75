"""tactile_markers node parameters: defaults (= config/tactile_markers.yaml) and validation naming
the bad parameter and value."""
from __future__ import annotations

from dataclasses import dataclass, field

from prisma_common.hand import FINGERS
from prisma_common.parameters import ParameterError, Params, check_fingers, check_positive


@dataclass
class TactileMarkersConfig(Params):
    fingers: list = field(default_factory=lambda: list(FINGERS))
    rate_hz: float = 30.0  # display rate: at most this many MarkerArrays per second
    taxel_pitch: float = 0.004  # m between taxel centres (the pad's, as in the description)
    cell_thickness: float = 0.001  # m: the drawn taxel cells' height above the pad
    contact_force_n: float = 0.1  # N of estimated Fz from which the contact point and force are drawn
    arrow_m_per_n: float = 0.02  # force arrow length per N
    arrow_max_length: float = 0.06  # m: longer arrows are cut to this

    def validate(self) -> None:
        check_fingers(self.fingers)
        for name in ("rate_hz", "taxel_pitch", "cell_thickness", "contact_force_n", "arrow_m_per_n",
                     "arrow_max_length"):
            check_positive(name, getattr(self, name))
        if self.rate_hz > 100.0:
            raise ParameterError("rate_hz", self.rate_hz, "a display rate of at most 100 Hz (the taxels' rate)")
