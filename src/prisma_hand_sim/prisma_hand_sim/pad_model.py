"""Optical fingertip pad model: contact (location, normal and shear force) -> 9 ADC counts.

Physics it imitates (the PRISMA optoelectronic taxel): under each taxel an LED and a
phototransistor face the inside of a deformable reflective cap. Pressing the cap brings the
reflecting surface closer, so MORE light reaches the phototransistor, and the emitter-follower
readout gives a HIGHER voltage. Contact therefore raises the voltage of the taxels under it; the
taxels away from it stay near their rest voltage. This is the polarity Algorithm 1 relies on
(a taxel is safe when v_i >= K * mean(v)).

Pad frame (origin at the pad centre, millimetres): +x toward the LEFT lateral side (column 2),
+y toward the TOP row (row 2). Taxel i = 3*row + col sits at ((col-1)*pitch, (row-1)*pitch).
The wrench frame has z = x cross y and its sign chosen so that the normal force pressing into
the pad is +Fz; shear_x/shear_y are the tangential forces the object applies to the pad.

Signal chain per sample (every constant is a PadParams field):
 1. spatial spread: local pressure p_i = Fz * exp(-|r_i - c|^2 / (2 sigma^2)); the contact patch
    grows with load: sigma = sigma0 + sigma_growth * Fz^(1/3) (Hertz-like contact radius);
 2. shear skew: shear drags the cap, shifting the deformation centre c toward the shear
    (shear_shift_mm_per_n) and tilting the cap, which adds a voltage plane
    shear_tilt_volts_per_n * (shear . r_i) / pitch (leading side up, trailing side down);
 3. hysteresis: the cap recovers more slowly than it is compressed; each taxel's effective
    pressure follows a relative play operator: on loading it equals p, on unloading it stays
    up to (1 + hysteresis) * p, so the unloading branch reads ~10% higher;
 4. saturating response: s_i = 1 - exp(-p_eff / pressure_sat_n);
 5. per-taxel rest offsets and gains: v_i = rest_i + gain_i * (span * s_i + tilt_i);
 6. supply rail: a smooth minimum with rail_volts (softness rail_softness_volts);
 7. analog noise (noise_lsb rms, in 12-bit LSB) then 12-bit quantisation, clipped to 0..4095.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from prisma_common.hand import ADC_LEVELS, ADC_MAX, N_TAXELS, TAXEL_PITCH_M, counts_to_voltages

# One physical sensor unit ("unit 0"): rest voltages and relative gains as measured on a pad.
# Gains have a standard deviation of ~0.14 around 1 (the paper's ~15% taxel-to-taxel spread).
UNIT0_REST_VOLTS = (0.42, 0.47, 0.39, 0.45, 0.41, 0.50, 0.44, 0.38, 0.46)
UNIT0_GAINS = (1.12, 0.91, 1.05, 0.83, 1.00, 1.18, 0.95, 1.21, 0.86)


@dataclass(frozen=True)
class PadParams:
    """Every imperfection of the pad model, in physical units."""

    pitch_mm: float = TAXEL_PITCH_M * 1e3  # centre-to-centre taxel spacing
    pad_size_mm: float = 14.0  # side of the square sensing surface (contacts beyond it still spread)
    rest_volts: tuple[float, ...] = UNIT0_REST_VOLTS  # per-taxel output with no contact
    gains: tuple[float, ...] = UNIT0_GAINS  # per-taxel relative sensitivity (~15% spread)
    span_volts: float = 2.8  # voltage rise of a unit-gain taxel at full local saturation
    pressure_sat_n: float = 2.0  # local pressure at which the response reaches 63% of span
    sigma0_mm: float = 3.2  # spatial spread of a light contact (Gaussian sigma)
    sigma_growth_mm: float = 0.5  # spread growth per N^(1/3) of normal load
    shear_shift_mm_per_n: float = 0.8  # deformation centre shift toward the shear
    shear_tilt_volts_per_n: float = 0.12  # cap tilt: voltage change one pitch from centre per N
    hysteresis: float = 0.10  # unloading branch reads up to this fraction higher in pressure
    rail_volts: float = 3.3  # supply rail the phototransistor output saturates at
    rail_softness_volts: float = 0.04  # how sharply the output bends onto the rail
    noise_lsb: float = 3.0  # analog noise rms before quantisation, in 12-bit LSB
    vref: float = 3.3  # ADC reference (VDD on the MAX11617)

    def __post_init__(self) -> None:
        if len(self.rest_volts) != N_TAXELS or len(self.gains) != N_TAXELS:
            raise ValueError("rest_volts and gains need 9 values each")
        for name in ("pitch_mm", "pad_size_mm", "span_volts", "pressure_sat_n", "sigma0_mm",
                     "rail_volts", "rail_softness_volts", "vref"):
            if getattr(self, name) <= 0:
                raise ValueError(f"PadParams.{name} must be > 0, got {getattr(self, name)}")
        for name in ("sigma_growth_mm", "hysteresis", "noise_lsb", "shear_shift_mm_per_n"):
            if getattr(self, name) < 0:
                raise ValueError(f"PadParams.{name} must be >= 0, got {getattr(self, name)}")

    def taxel_positions_mm(self) -> np.ndarray:
        """(9, 2) taxel centres (x, y) in the pad frame."""
        index = np.arange(N_TAXELS)
        col, row = index % 3, index // 3
        return np.stack([(col - 1) * self.pitch_mm, (row - 1) * self.pitch_mm], axis=1).astype(float)

    @property
    def lsb_volts(self) -> float:
        return self.vref / ADC_LEVELS


@dataclass(frozen=True)
class PadContact:
    """Contact on the pad: location (mm, pad frame), normal force (N, pressing in) and shear (N)."""

    x_mm: float
    y_mm: float
    normal_n: float
    shear_x_n: float = 0.0
    shear_y_n: float = 0.0


def _finite(value: float) -> float:
    """np.nan_to_num for one number: NaN -> 0, +-inf -> the largest finite float."""
    value = float(value)
    if value != value:
        return 0.0
    return max(-_FLOAT_MAX, min(_FLOAT_MAX, value))


_FLOAT_MAX = float(np.finfo(float).max)


class PadModel:
    """Stateful (hysteresis) pad simulator. Deterministic for a given seed and input sequence."""

    def __init__(self, params: PadParams | None = None, seed: int = 0) -> None:
        self.params = params or PadParams()
        self._rng = np.random.default_rng(seed)
        self._positions = self.params.taxel_positions_mm()
        self._rest = np.asarray(self.params.rest_volts, dtype=float)
        self._gains = np.asarray(self.params.gains, dtype=float)
        self._memory = np.zeros(N_TAXELS)  # effective (hysteretic) pressure per taxel

    def reset(self) -> None:
        """Forget the loading history (a fully relaxed pad)."""
        self._memory[:] = 0.0

    # -- stateless parts -------------------------------------------------------------------
    def local_pressure(self, x_mm, y_mm, normal_n, shear_x_n=0.0, shear_y_n=0.0) -> np.ndarray:
        """(N, 9) local pressure in N before hysteresis; no contact = normal_n <= 0 or NaN."""
        p = self.params
        fz = np.nan_to_num(np.atleast_1d(np.asarray(normal_n, dtype=float)), nan=0.0).clip(min=0.0)
        x, y, sx, sy = (np.broadcast_to(np.nan_to_num(np.asarray(v, dtype=float)), fz.shape)
                        for v in (x_mm, y_mm, shear_x_n, shear_y_n))
        cx = x + p.shear_shift_mm_per_n * sx
        cy = y + p.shear_shift_mm_per_n * sy
        sigma = p.sigma0_mm + p.sigma_growth_mm * np.cbrt(fz)
        d2 = (self._positions[None, :, 0] - cx[:, None]) ** 2 + (self._positions[None, :, 1] - cy[:, None]) ** 2
        return fz[:, None] * np.exp(-d2 / (2.0 * sigma[:, None] ** 2))

    def _tilt(self, shear_x_n, shear_y_n) -> np.ndarray:
        p = self.params
        sx = np.atleast_1d(np.nan_to_num(np.asarray(shear_x_n, dtype=float)))
        sy = np.atleast_1d(np.nan_to_num(np.asarray(shear_y_n, dtype=float)))
        along = sx[:, None] * self._positions[None, :, 0] + sy[:, None] * self._positions[None, :, 1]
        return p.shear_tilt_volts_per_n * along / p.pitch_mm

    def response_volts(self, effective_pressure: np.ndarray, shear_x_n, shear_y_n) -> np.ndarray:
        """Noise-free analog output (N, 9) for given effective pressures and shear."""
        p = self.params
        s = 1.0 - np.exp(-effective_pressure / p.pressure_sat_n)
        v = self._rest + self._gains * (p.span_volts * s + self._tilt(shear_x_n, shear_y_n))
        # smooth min(v, rail): exact far below the rail, bends onto it within a few softness widths
        return p.rail_volts - p.rail_softness_volts * np.logaddexp(0.0, (p.rail_volts - v) / p.rail_softness_volts)

    # -- stateful sampling -----------------------------------------------------------------
    def _hysteresis(self, pressure: np.ndarray) -> np.ndarray:
        """Relative play operator along the sequence; updates the stored memory."""
        upper = pressure * (1.0 + self.params.hysteresis)
        out = np.empty_like(pressure)
        memory = self._memory
        for t in range(pressure.shape[0]):  # sequential by nature: each step depends on the last
            memory = np.minimum(np.maximum(memory, pressure[t]), upper[t])
            out[t] = memory
        self._memory = memory.copy()
        return out

    def sample_sequence(self, x_mm, y_mm, normal_n, shear_x_n=0.0, shear_y_n=0.0) -> np.ndarray:
        """Counts (N, 9) uint16 for a sequence of contacts (arrays of length N, normal_n <= 0 or
        NaN = no contact). Equivalent to N successive `sample` calls."""
        fz = np.atleast_1d(np.asarray(normal_n, dtype=float))
        in_contact = np.nan_to_num(fz, nan=0.0) > 0
        sx = np.where(in_contact, np.broadcast_to(np.nan_to_num(np.asarray(shear_x_n, dtype=float)), fz.shape), 0.0)
        sy = np.where(in_contact, np.broadcast_to(np.nan_to_num(np.asarray(shear_y_n, dtype=float)), fz.shape), 0.0)
        pressure = self.local_pressure(x_mm, y_mm, fz, sx, sy)
        effective = self._hysteresis(pressure)
        volts = self.response_volts(effective, sx, sy)
        volts = volts + self._rng.standard_normal(volts.shape) * (self.params.noise_lsb * self.params.lsb_volts)
        counts = np.rint(volts / self.params.lsb_volts)
        return np.clip(counts, 0, ADC_MAX).astype(np.uint16)

    def sample(self, contact: PadContact | None) -> np.ndarray:
        """Counts uint16[9] for one contact (None = nothing touching the pad).

        The same arithmetic as `sample_sequence` on one row, bit for bit (a test holds them equal),
        without its array set-up: this runs for every finger of every simulated scan."""
        p = self.params
        fz = 0.0 if contact is None else _finite(contact.normal_n)
        if contact is not None and fz > 0.0:
            x, y = _finite(contact.x_mm), _finite(contact.y_mm)
            sx, sy = _finite(contact.shear_x_n), _finite(contact.shear_y_n)
        else:  # nothing touching: the pad relaxes and no shear acts
            fz = x = y = sx = sy = 0.0
        cx = x + p.shear_shift_mm_per_n * sx
        cy = y + p.shear_shift_mm_per_n * sy
        sigma = p.sigma0_mm + p.sigma_growth_mm * np.cbrt(fz)
        d2 = (self._positions[:, 0] - cx) ** 2 + (self._positions[:, 1] - cy) ** 2
        pressure = fz * np.exp(-d2 / (2.0 * sigma ** 2))
        self._memory = np.minimum(np.maximum(self._memory, pressure), pressure * (1.0 + p.hysteresis))
        # response_volts, one row
        along = sx * self._positions[:, 0] + sy * self._positions[:, 1]
        tilt = p.shear_tilt_volts_per_n * along / p.pitch_mm
        v = self._rest + self._gains * (p.span_volts * (1.0 - np.exp(-self._memory / p.pressure_sat_n)) + tilt)
        volts = p.rail_volts - p.rail_softness_volts * np.logaddexp(0.0, (p.rail_volts - v) / p.rail_softness_volts)
        volts = volts + self._rng.standard_normal(volts.shape) * (p.noise_lsb * p.lsb_volts)
        return np.clip(np.rint(volts / p.lsb_volts), 0, ADC_MAX).astype(np.uint16)

    def voltages(self, contact: PadContact | None) -> np.ndarray:
        """float32[9] volts of one sample (quantised like the real ADC)."""
        return counts_to_voltages(self.sample(contact), self.params.vref)

    def noiseless_voltages(self, contact: PadContact | None) -> np.ndarray:
        """Analog output without noise, quantisation or hysteresis memory (for checks and plots)."""
        if contact is None:
            return self.response_volts(np.zeros((1, N_TAXELS)), 0.0, 0.0)[0]
        pressure = self.local_pressure(contact.x_mm, contact.y_mm, contact.normal_n,
                                       contact.shear_x_n, contact.shear_y_n)
        return self.response_volts(pressure, contact.shear_x_n, contact.shear_y_n)[0]
