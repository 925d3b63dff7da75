"""Pad model and scripted contact source."""
import numpy as np
import pytest

from prisma_common.hand import counts_to_voltages
from prisma_hand_sim.contact_source import ContactSource, ScriptedContactSource
from prisma_hand_sim.pad_model import PadContact, PadModel, PadParams

# The pad's edges by taxel index (docs/architecture.md's taxel numbering), as
# prisma_tactile_driver.taxels.EDGES has them (prisma_hand_sim sits below the driver).
EDGES = {"bottom": (0, 1, 2), "top": (6, 7, 8), "right": (0, 3, 6), "left": (2, 5, 8)}


def algorithm1(volts: np.ndarray, k: float) -> tuple[np.ndarray, list[str]]:
    """Algorithm 1 as the controllers apply it: safe when v_i >= K * mean; an edge is lost when
    all three of its taxels are unsafe."""
    safe = volts >= k * volts.mean()
    return safe, [edge for edge, idx in EDGES.items() if not safe[list(idx)].any()]


def mean_voltages(contact, n=50, seed=0):
    model = PadModel(seed=seed)
    return np.mean([model.voltages(contact) for _ in range(n)], axis=0)


def test_no_contact_reads_rest_offsets_with_at_least_3_lsb_noise():
    model = PadModel(seed=1)
    counts = np.array([model.sample(None) for _ in range(4000)], dtype=float)
    lsb = 3.3 / 4096
    np.testing.assert_allclose(counts.mean(0) * lsb, PadParams().rest_volts, atol=0.003)
    noise = counts.std(0)
    assert np.all(noise >= 2.9) and np.all(noise <= 3.3)  # 3 LSB rms + quantisation


def test_gain_spread_is_about_15_percent():
    gains = np.array(PadParams().gains)
    assert gains.mean() == pytest.approx(1.0, abs=0.03)
    assert 0.10 <= gains.std() <= 0.18


def test_deterministic_for_seed_and_input_sequence():
    contacts = [None, PadContact(1, 2, 0.5), PadContact(1, 2, 2.0, 0.3, -0.2), PadContact(1, 2, 1.0), None]
    def run(seed):
        model = PadModel(seed=seed)
        return [model.sample(c) for c in contacts]

    runs = [run(7), run(7)]
    np.testing.assert_array_equal(runs[0], runs[1])
    other = run(8)
    assert not np.array_equal(runs[0], other)
    # the batch path equals successive single samples
    model = PadModel(seed=7)
    batch = model.sample_sequence([0, 1, 1, 1, 0], [0, 2, 2, 2, 0], [0, 0.5, 2.0, 1.0, 0],
                                  [0, 0, 0.3, 0, 0], [0, 0, -0.2, 0, 0])
    np.testing.assert_array_equal(batch, np.array(runs[0]))


def test_contact_raises_the_voltage_under_it_and_grows_with_force():
    rest = np.array(PadParams().rest_volts)
    light, firm = mean_voltages(PadContact(0, 0, 0.5)), mean_voltages(PadContact(0, 0, 3.0))
    assert np.all(light > rest + 0.02)
    assert np.all(firm > light + 0.3)
    assert np.argmax(firm - rest) == 4  # the centre taxel rises most
    over_taxel_2 = mean_voltages(PadContact(4, -4, 2.0))  # taxel 2: bottom row, left column
    assert np.argmax(over_taxel_2 - rest) == 2


def test_response_saturates_and_never_exceeds_the_rail():
    model = PadModel()
    rises = [model.noiseless_voltages(PadContact(0, 0, f))[4] for f in (1, 2, 4, 8, 16)]
    steps = np.diff(rises)
    assert np.all(steps > 0) and np.all(np.diff(steps) < 0)  # rising but saturating
    huge = PadModel(seed=3)
    counts = np.array([huge.sample(PadContact(0, 4, 50.0, 0.0, 1.5)) for _ in range(200)])
    assert counts.max() <= 4095
    assert counts[:, 7].mean() * 3.3 / 4096 > 3.15  # the high-gain taxel 7 sits on the 3.3 V rail


def test_algorithm1_centre_contact_all_safe_and_side_contact_loses_opposite_edge():
    for force in (0.5, 1.0, 2.0, 4.0):
        safe, lost = algorithm1(mean_voltages(PadContact(0, 0, force)), 0.7)
        assert safe.all(), (force, safe)
    for k in (0.6, 0.7, 0.8, 0.9):
        # contact near the left edge (+x): right edge 0-3-6 lost, left edge safe
        _, lost = algorithm1(mean_voltages(PadContact(5.5, 0, 2.0)), k)
        assert lost == ["right"], (k, lost)
        _, lost = algorithm1(mean_voltages(PadContact(-5.5, 0, 2.0)), k)
        assert lost == ["left"], (k, lost)
        _, lost = algorithm1(mean_voltages(PadContact(0, 5.5, 2.0)), k)
        assert lost == ["bottom"], (k, lost)
        _, lost = algorithm1(mean_voltages(PadContact(0, -5.5, 2.0)), k)
        assert lost == ["top"], (k, lost)


def test_shear_skews_the_deformation_toward_the_shear():
    still = mean_voltages(PadContact(0, 0, 2.0))
    sheared = mean_voltages(PadContact(0, 0, 2.0, 1.0, 0.0))
    left, right = list(EDGES["left"]), list(EDGES["right"])
    assert (sheared[left] - still[left]).mean() > 0.1
    assert (sheared[right] - still[right]).mean() < -0.1


def test_hysteresis_unloading_branch_reads_about_10_percent_higher_pressure():
    params = PadParams(noise_lsb=0.0)
    model = PadModel(params)
    forces = np.concatenate([np.linspace(0, 4, 200), np.linspace(4, 0, 200)])
    volts = counts_to_voltages(model.sample_sequence(np.zeros(400), np.zeros(400), forces))[:, 4]

    def at(f, branch):
        return volts[branch][np.argmin(np.abs(forces[branch] - f))]

    loading, unloading = slice(0, 200), slice(200, 400)
    for f in (1.0, 2.0, 3.0):
        assert at(f, unloading) > at(f, loading) + 0.02
        # unloading at f reads like loading at ~1.1 f
        assert at(f, unloading) == pytest.approx(at(1.1 * f, loading), abs=0.02)
    rest = params.rest_volts[4]
    assert volts[-1] == pytest.approx(rest, abs=0.002)  # fully released pad forgets
    model.reset()


def test_scripted_source_cycles_press_slide_roll_release():
    source = ScriptedContactSource()
    assert isinstance(source, ContactSource)

    def at(t, finger="thumb"):
        return source.contact(finger, int(t * 1e9))

    assert at(0.5) is None and at(7.0) is None
    press = at(1.5)
    assert press.x_mm == 0 and 0 < press.normal_n < 2.0
    slide = at(3.0)
    assert slide.x_mm > 1.0 and slide.shear_x_n == pytest.approx(0.4 * 2.0)
    roll = at(4.5)
    assert roll.y_mm > 3.0 and roll.normal_n == pytest.approx(2.0)
    release = at(6.0)
    assert release.x_mm == -5.0 and 0 < release.normal_n < 2.0
    assert at(1.5 + 8.0) == press  # periodic
    assert at(1.5, "index") != press  # fingers are phase shifted
    with pytest.raises(ValueError, match="pinky"):
        source.contact("pinky", 0)


def test_single_sample_path_equals_the_sequence_path_bit_for_bit():
    # sample() has its own one-row arithmetic (the sim driver's hot path): same counts, same noise stream
    rng = np.random.default_rng(3)
    contacts = [None if rng.random() < 0.3 else
                PadContact(*rng.normal(0, 3, 2), rng.uniform(-0.5, 4.0), *rng.normal(0, 0.5, 2))
                for _ in range(2000)]
    contacts += [PadContact(float("nan"), 1.0, 1.0), PadContact(0.0, 0.0, float("nan")),
                 PadContact(1.0, 1.0, 2.0, float("nan"), 0.1), PadContact(0.0, 0.0, 0.0, float("inf"), 1.0)]

    def column(name: str) -> list[float]:
        return [0.0 if c is None else getattr(c, name) for c in contacts]

    model = PadModel(seed=5)
    single = np.array([model.sample(c) for c in contacts])
    batch = PadModel(seed=5).sample_sequence(column("x_mm"), column("y_mm"), column("normal_n"),
                                             column("shear_x_n"), column("shear_y_n"))
    np.testing.assert_array_equal(single, batch)
