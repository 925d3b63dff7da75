"""Which form of a sample stream a node takes: per finger or per hand, each sample exactly once.

The tactile driver publishes every taxel sample twice: on /prisma/<finger>/taxels (for rqt_plot,
recorders and any single-finger user) and inside one /prisma/hand/taxels per poll; the force
estimator does the same with wrenches. A node that uses all five fingers pays rclpy's per-message
cost once per scan on the per-hand topic instead of five times, but a bag recorded with only the
per-finger topics must still drive it. So the node listens to both until the first per-hand message
arrives, then to that one only. Around the switch both forms may carry the same samples: a
per-hand sample is skipped when the per-finger stream already delivered its finger at that stamp
or later.
"""
from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class HandInput:
    switched: bool = False  # True from the first per-hand message on
    # newest stamp per finger that came per finger, until the per-hand stream is past it
    _overlap_ns: dict[str, int] = field(default_factory=dict)

    def take_finger(self, finger: str, stamp_ns: int) -> bool:
        """True when a per-finger sample is to be used (only before the switch)."""
        if self.switched:
            return False
        self._overlap_ns[finger] = max(stamp_ns, self._overlap_ns.get(finger, stamp_ns))
        return True

    def take_hand(self, finger: str, stamp_ns: int) -> bool:
        """True when a sample of a per-hand message is to be used (switches to the per-hand form)."""
        self.switched = True
        last = self._overlap_ns.get(finger)
        if last is None:
            return True
        if stamp_ns <= last:
            return False
        del self._overlap_ns[finger]  # this finger is past the overlap
        return True
