"""Glove converters, tested by CDR round trip through the typestore."""
import numpy as np
import pytest

from prisma_common.diagnostics import ERROR, DiagnosticStatusData, diagnostics_from_msg, diagnostics_to_msg
from prisma_common.typestore import types
from prisma_testing.cdr import cdr_round_trip
from stag_glove.processing import FrameProcessor
from stag_glove.ros_conversions import (
    Estimate,
    WeightResult,
    estimate_from_msg,
    estimate_to_msg,
    glove_frame_from_msg,
    glove_frame_to_msg,
    image_to_pressure,
    pressure_image_msg,
    weight_from_msg,
    weight_to_msg,
)


def processed(shorted=False):
    raw = np.random.default_rng(0).integers(450, 700, (32, 32)).astype(np.uint16)
    if shorted:
        raw[1, 2] = 1000
    return FrameProcessor().process(raw, stamp_ns=1_700_000_000_123_456_789)


def test_glove_frame_round_trip():
    frame = processed(shorted=True)
    msg = cdr_round_trip(glove_frame_to_msg(types, frame, "stag_glove"))
    assert msg.header.frame_id == "stag_glove"
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (1_700_000_000, 123_456_789)
    back = glove_frame_from_msg(msg)
    assert back.stamp_ns == frame.stamp_ns
    np.testing.assert_array_equal(back.raw, frame.raw)
    np.testing.assert_array_equal(back.pressure, frame.pressure)
    assert back.shorted and not back.contact


def test_glove_frame_with_inconsistent_size_is_rejected():
    msg = glove_frame_to_msg(types, processed(), "g")
    msg.rows = 31
    with pytest.raises(ValueError, match="31x32"):
        glove_frame_from_msg(msg)


def test_pressure_image_is_32fc1():
    frame = processed()
    msg = cdr_round_trip(pressure_image_msg(frame, types, "stag_glove"))
    assert (msg.height, msg.width, msg.encoding, msg.step, msg.is_bigendian) == (32, 32, "32FC1", 128, 0)
    np.testing.assert_array_equal(image_to_pressure(msg), frame.pressure)


def test_estimates_round_trip():
    est = Estimate("mug", 0.75, ["ball", "mug"], np.array([0.25, 0.75], np.float32), 8)
    back = estimate_from_msg(cdr_round_trip(estimate_to_msg(types, est, 5, "stag_glove")))
    assert (back.label, back.labels, back.frames_used) == ("mug", ["ball", "mug"], 8)
    assert back.confidence == pytest.approx(0.75)
    np.testing.assert_allclose(back.probabilities, [0.25, 0.75])
    w = weight_from_msg(cdr_round_trip(weight_to_msg(types, WeightResult(123.5, 98.25), 5, "g")))
    assert (w.grams, w.baseline_grams) == (123.5, 98.25)


def test_diagnostics_round_trip():
    status = DiagnosticStatusData("glove_driver: readout", ERROR, "disconnected", "stag", {"crc_errors": "3"})
    back = diagnostics_from_msg(cdr_round_trip(diagnostics_to_msg(types, 9, [status])))
    assert back == [status]
