"""Fixtures shared by stag_glove's tests."""
import pytest
import torch

from stag_glove import glove_perception_core


@pytest.fixture(autouse=True)
def restore_threads():
    """glove_perception and the commands limit torch/BLAS threads for their whole process; give the
    other tests theirs back."""
    before = torch.get_num_threads()
    yield
    torch.set_num_threads(before)
    if glove_perception_core._thread_limit is not None:
        glove_perception_core._thread_limit.restore_original_limits()
        glove_perception_core._thread_limit = None


@pytest.fixture
def driver_cls():
    from stag_glove.glove_driver_node import GloveDriverNode  # rclpy: only in tests that have ROS
    return GloveDriverNode


@pytest.fixture
def perception_cls():
    from stag_glove.glove_perception_node import GlovePerceptionNode  # rclpy: only in tests that have ROS
    return GlovePerceptionNode
