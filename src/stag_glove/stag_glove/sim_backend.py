"""A synthetic glove stream at the glove's frame rate."""
from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from .backend import BackendStatus, PacedBackend

# The synthetic stream grasps objects as the object set records them: held, never lifted. The weight
# network (trained on lifts) then reads the grip of a hand that carries no load: ~24 g whatever is
# held (docs/glove.md, "Perception node behaviour"). Said where a user of the sim backend looks.
NO_LOAD_NOTE = ("synthetic glove: objects are held, never lifted, so /stag/weight has no load to read "
                "(about 24 g whatever is held; docs/glove.md)")


class SimGloveBackend(PacedBackend):
    """Synthetic glove stream (empty hand first, then grasps of random objects)."""

    def __init__(self, rate_hz: float = 7.3, seed: int = 0, short_probability: float = 0.0) -> None:
        from .synthetic import SyntheticConfig, SyntheticGlove  # heavy-ish import only when used

        self.glove = SyntheticGlove(SyntheticConfig(seed=seed, short_probability=short_probability))
        self._stream = self.glove.stream()
        self.truth: tuple[str, bool] | None = None
        super().__init__(self._frames(), rate_hz)

    def _frames(self) -> Iterator[np.ndarray]:
        for raw, name, touching in self._stream:
            self.truth = (name, touching)
            yield raw

    def status(self) -> BackendStatus:
        return BackendStatus(True, f"simulated glove; {NO_LOAD_NOTE}", {"frames": str(self.frames_sent)})
