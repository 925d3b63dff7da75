"""The `rig` fixture of prisma_hand_emulator's tests: Rigs (prisma_testing.emulator_rig) closed after
the test."""
from __future__ import annotations

import pytest

from prisma_testing.emulator_rig import Rig


@pytest.fixture
def rig(tmp_path):
    """rig(world="pinch_ball", link="serial", root=tmp_path): a Rig, closed after the test."""
    rigs: list[Rig] = []
    yield lambda world="pinch_ball", link="serial", root=tmp_path: rigs.append(Rig(root, world, link)) or rigs[-1]
    for r in rigs:
        r.close()
