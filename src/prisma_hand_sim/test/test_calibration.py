"""Synthetic calibration sets from the pad model."""
import numpy as np
import pytest
from sklearn.linear_model import Ridge
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import PolynomialFeatures

from prisma_hand_sim.calibration import CalibrationSet, generate_calibration_set, generate_trajectory


@pytest.fixture(scope="module")
def mixed():
    return generate_calibration_set(20_000, seed=0)


def test_shapes_dtypes_and_exact_length(mixed):
    assert len(mixed) == 20_000
    assert mixed.voltages.dtype == np.float32 and mixed.voltages.shape == (20_000, 9)
    assert mixed.wrench.dtype == np.float32 and mixed.wrench.shape == (20_000, 6)
    assert mixed.stamp_ns.dtype == np.int64 and mixed.trajectory.dtype == np.int32
    np.testing.assert_array_equal(np.diff(mixed.stamp_ns), 10_000_000)  # 100 Hz
    assert set(np.unique(mixed.kind)) == {"push", "slide", "roll"}
    # trajectory ids are contiguous runs, each of one kind
    assert np.all(np.diff(mixed.trajectory) >= 0)
    for tid in np.unique(mixed.trajectory)[:20]:
        assert len(set(mixed.kind[mixed.trajectory == tid])) == 1


def test_seeded_and_deterministic():
    a, b = generate_calibration_set(3000, seed=5), generate_calibration_set(3000, seed=5)
    np.testing.assert_array_equal(a.voltages, b.voltages)
    np.testing.assert_array_equal(a.wrench, b.wrench)
    c = generate_calibration_set(3000, seed=6)
    assert not np.array_equal(a.wrench, c.wrench)


def test_force_ranges_match_the_rig(mixed):
    fx, fy, fz = mixed.wrench[:, 0], mixed.wrench[:, 1], mixed.wrench[:, 2]
    assert fz.min() == 0.0 and 4.5 < fz.max() < 5.6
    assert np.abs(mixed.wrench[:, :2]).max() <= 1.5 + 1e-6
    assert np.abs(fx).max() > 1.0 and np.abs(fy).max() > 1.0
    loaded = fz > 0
    assert 0.6 < loaded.mean() < 0.95  # unloaded gaps between trajectories
    np.testing.assert_array_equal(mixed.wrench[~loaded], 0.0)
    assert np.isnan(mixed.contact_mm[~loaded]).all()


def test_torque_is_r_cross_f_about_the_pad_centre(mixed):
    loaded = mixed.wrench[:, 2] > 0
    x, y = mixed.contact_mm[loaded, 0] * 1e-3, mixed.contact_mm[loaded, 1] * 1e-3
    fx, fy, fz, tx, ty, tz = mixed.wrench[loaded].T
    np.testing.assert_allclose(tx, y * fz, atol=1e-6)
    np.testing.assert_allclose(ty, -x * fz, atol=1e-6)
    np.testing.assert_allclose(tz, x * fy - y * fx, atol=1e-6)


def test_slide_shear_follows_travel_with_friction_03_to_06():
    slide = generate_trajectory("slide", 4000, seed=2)
    assert set(slide.kind) == {"slide"}
    fx, fy, fz = slide.wrench[:, :3].T
    shear = np.hypot(fx, fy)
    sliding = shear > 0.2
    ratio = shear[sliding] / fz[sliding]
    assert ratio.max() <= 0.6 + 1e-3 and np.percentile(ratio, 90) >= 0.3
    # the shear points along the direction the contact travels
    velocity = np.gradient(slide.contact_mm, axis=0)
    moving = sliding & (np.hypot(*velocity.T) > 0.02)
    cos = (velocity[moving] * slide.wrench[moving, :2]).sum(1) / (
        np.hypot(*velocity[moving].T) * shear[moving])
    assert np.median(cos) > 0.99


def test_push_is_mostly_normal_and_roll_moves_the_contact():
    push = generate_trajectory("push", 3000, seed=3)
    loaded = push.wrench[:, 2] > 0.5
    assert np.percentile(np.hypot(*push.wrench[loaded, :2].T) / push.wrench[loaded, 2], 95) < 0.15
    roll = generate_trajectory("roll", 3000, seed=4)
    for tid in np.unique(roll.trajectory)[:5]:
        loc = roll.contact_mm[(roll.trajectory == tid) & (roll.wrench[:, 2] > 0.3)]
        assert np.ptp(loc[:, 0]) + np.ptp(loc[:, 1]) > 2.0
    with pytest.raises(ValueError, match="twist"):
        generate_trajectory("twist", 10, seed=0)


def test_save_load_round_trip(tmp_path, mixed):
    path = tmp_path / "cal.npz"
    mixed.save(path)
    back = CalibrationSet.load(path)
    for name in ("voltages", "wrench", "stamp_ns", "trajectory", "kind", "contact_mm"):
        np.testing.assert_array_equal(getattr(back, name), getattr(mixed, name))
    np.savez(tmp_path / "junk.npz", a=np.zeros(3))
    with pytest.raises(ValueError, match="missing arrays"):
        CalibrationSet.load(tmp_path / "junk.npz")


@pytest.mark.filterwarnings("ignore:.*ill-conditioned")  # cubic features are collinear; ridge copes
def test_force_is_recoverable_but_not_linear(mixed):
    """Cubic features recover Fz and shear far better than a linear map: the mapping carries
    the information (a CNN does better still) without being a linear function of the voltages."""
    test_push = generate_trajectory("push", 5000, seed=100)
    test_slide = generate_trajectory("slide", 5000, seed=101)
    errors = {}
    for degree in (1, 3):
        model = make_pipeline(PolynomialFeatures(degree), Ridge(1e-3)).fit(mixed.voltages, mixed.wrench[:, :3])
        fz_mse = np.mean((model.predict(test_push.voltages)[:, 2] - test_push.wrench[:, 2]) ** 2)
        shear_mse = np.mean((model.predict(test_slide.voltages)[:, :2] - test_slide.wrench[:, :2]) ** 2, axis=0)
        errors[degree] = (fz_mse, shear_mse)
    assert errors[3][0] < 0.05 and np.all(errors[3][1] < 0.04)
    assert errors[1][0] > 3 * errors[3][0]
    assert np.all(errors[1][1] > 1.3 * errors[3][1])


def test_calibration_set_and_figures_are_written_atomically(tmp_path, monkeypatch):
    """A failure while numpy writes the archive leaves no .npz behind (and none that loads)."""
    cal = generate_calibration_set(300, seed=1)
    calls = []

    def failing(stream, **arrays):
        calls.append(sorted(arrays))
        stream.write(b"PK\x03\x04 partial")
        raise KeyboardInterrupt

    monkeypatch.setattr(np, "savez_compressed", failing)
    with pytest.raises(KeyboardInterrupt):
        cal.save(tmp_path / "cal.npz")
    assert calls and not (tmp_path / "cal.npz").exists()
    assert not [p.name for p in tmp_path.iterdir() if ".partial-" in p.name]  # no staging left
    monkeypatch.undo()
    cal.save(tmp_path / "cal.npz")
    assert len(CalibrationSet.load(tmp_path / "cal.npz")) == 300
