"""tactile_markers parameters: defaults = config/tactile_markers.yaml, invalid values named."""
from __future__ import annotations

import pytest
from prisma_visualization.node_config import TactileMarkersConfig, TendonStretchConfig

from prisma_common.parameters import ParameterError
from prisma_testing.repo_paths import CONFIG, node_parameters


def test_defaults_are_the_shipped_parameter_file():
    assert TactileMarkersConfig().as_parameters() == node_parameters(CONFIG / "tactile_markers.yaml",
                                                                     "tactile_markers")


@pytest.mark.parametrize("name, value, message", [
    ("rate_hz", 0.0, "invalid parameter 'rate_hz' = 0.0: must be > 0.0 and <= 100.0"),
    ("rate_hz", 500.0, "invalid parameter 'rate_hz' = 500.0: must be > 0.0 and <= 100.0"),
    ("fingers", ["thumb", "pinky"], "invalid parameter 'fingers' = ['thumb', 'pinky']: 'pinky' is not one of"),
    ("arrow_m_per_n", -0.02, "invalid parameter 'arrow_m_per_n' = -0.02: must be > 0.0 and <= 1.0"),
])
def test_invalid_values_are_named(name, value, message):
    with pytest.raises(ParameterError, match=message.replace("[", r"\[").replace("]", r"\]").replace("(", r"\(")):
        TactileMarkersConfig.from_parameters({name: value})


def test_tendon_stretch_defaults_are_the_shipped_parameter_file():
    assert TendonStretchConfig().as_parameters() == node_parameters(CONFIG / "tendon_stretch.yaml", "tendon_stretch")
