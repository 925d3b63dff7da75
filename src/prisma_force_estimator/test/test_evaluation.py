"""Held-out push/slide evaluation: metrics on real numbers, table and plots."""
import numpy as np
import pytest

from prisma_force_estimator.bundle import save_untrained_bundle
from prisma_force_estimator.evaluation import (
    EvalResult,
    evaluate,
    held_out_tests,
    low_force_mae,
    plot_tests,
    results_table,
)
from prisma_force_estimator.inference import ForceEstimator


def test_low_force_mae_uses_contact_samples_under_the_limit():
    ref = np.zeros((4, 6))
    ref[:, 2] = [0.0, 0.5, 1.0, 2.0]  # untouched, two low-force samples, one above 1.2 N
    pred = ref.copy()
    pred[:, 0] += [9.0, 0.1, 0.3, 9.0]  # big errors only where they must not count
    pred[:, 2] += [9.0, -0.2, 0.2, 9.0]
    mae, n = low_force_mae([pred], [ref])
    assert n == 2
    assert mae["fx"] == pytest.approx(0.2) and mae["fz"] == pytest.approx(0.2) and mae["fy"] == 0.0


def test_targets_are_the_papers_cnn2_figures():
    r = EvalResult("x", "cnn2", 0.19, 0.015, 0.008, {"fx": 0.15, "fy": 0.1, "fz": 0.1}, 10)
    assert all(r.meets_targets().values())
    r = EvalResult("x", "cnn2", 0.2, 0.015, 0.0081, {"fx": 0.16, "fy": 0.1, "fz": 0.1}, 10)
    assert r.meets_targets() == {"push_fz": False, "slide_fx": True, "slide_fy": False, "low_force_mae": False}


@pytest.fixture(scope="module")
def tests_small():
    return held_out_tests(push_samples=600, slide_samples=600)


def test_held_out_sets_are_push_and_slide_only(tests_small):
    assert len(tests_small.push) == 600 and len(tests_small.slide) == 600
    # slides carry shear, pushes barely any
    assert np.abs(tests_small.slide.wrench[:, :2]).max() > 0.2
    assert tests_small.push.wrench[:, 2].max() > 0.2


def test_evaluate_computes_mse_against_the_reference(tests_small, tmp_path):
    est = ForceEstimator.from_bundle(save_untrained_bundle(tmp_path / "cnn", "cnn"))
    r = evaluate(est, tests_small, "cnn-untrained")
    pred = est.estimate(tests_small.push.voltages)
    assert r.push_fz_mse == pytest.approx(np.mean((pred[:, 2] - tests_small.push.wrench[:, 2]) ** 2))
    slide = est.estimate(tests_small.slide.voltages)
    assert r.slide_fy_mse == pytest.approx(np.mean((slide[:, 1] - tests_small.slide.wrench[:, 1]) ** 2))
    assert np.isnan(r.push_pred[:, 3:]).all()  # a force-only model has no torque columns
    table = results_table([r])
    assert "| cnn-untrained |" in table and f"{r.push_fz_mse:.4f}" in table
    paths = plot_tests([r, r], tests_small, tmp_path / "img", prefix="t_")
    assert [p.name for p in paths] == ["t_push_fz.png", "t_slide_fxfy.png", "t_error_vs_force.png"]
    for p in paths:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and p.stat().st_size < 300_000
