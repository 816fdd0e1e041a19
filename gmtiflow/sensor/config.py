"""Configuration schema of the GMTI sensor model (paper Table 1, DESIGN §5).

Every parameter of the paper's Table 1 is a field here, with its unit in the name.  Angles are
degrees in the config (radians in code).  Sensor angles are in the antenna frame
(:mod:`gmtiflow.sensor.antenna`): azimuth = scan angle off boresight, + clockwise seen from above;
elevation + up, measured in the rolled antenna frame (so a target below the horizon of a level
antenna has a negative elevation).

Range and cross-field rules live in :meth:`SensorConfig.problems` (DESIGN's config conventions);
:func:`gmtiflow.config.validate` turns them into one :class:`~gmtiflow.errors.ConfigError`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from enum import Enum
from typing import Any, Dict, List, Optional

from gmtiflow import schema
from gmtiflow.schema import Problem

#: Speed of light in vacuum (m/s).
C_MPS = 299_792_458.0
#: Boltzmann constant (J/K).
K_BOLTZMANN = 1.380649e-23

SNR_FORMS = ("radar_equation", "reference")

FREQ_RANGE_HZ = (3.0e7, 3.0e11)
"""Carrier frequencies ``freq_hz`` accepts: VHF to millimetre wave (IEEE radar bands, λ 10 m
to 1 mm).  Airborne GMTI radars work from UHF (foliage-penetrating, ~0.4 GHz) to Ku/Ka band
(~17 / 35 GHz), most at X band (10 GHz); a value outside is a unit slip (``freq_hz=10`` for
10 GHz), which used to be blamed on ``aperture_m`` (a beamwidth λ/d_a of 2.5e7)."""


@dataclass
class RcsConfig:
    """Radar cross-section model of one vehicle type.

    Either a constant ``rcs_dbsm`` or, when ``table`` is set, an aspect-angle table: a CSV file
    with the header ``aspect_deg,rcs_dbsm`` and one row per angle in [0, 360), strictly
    increasing, interpolated linearly and periodically (:mod:`gmtiflow.sensor.rcs`).  A relative
    ``table`` path is looked up first from the working directory, then inside the packaged
    ``conf/`` directory (e.g. ``sensor/rcs/truck.csv``).
    """

    rcs_dbsm: float = 10.0
    table: Optional[str] = None

    def problems(self) -> List[Problem]:
        out = []
        if not (isinstance(self.rcs_dbsm, (int, float)) and math.isfinite(self.rcs_dbsm)
                and -60.0 <= self.rcs_dbsm <= 80.0):
            out.append(Problem("rcs_dbsm", f"must be a finite number in [-60, 80] dBsm, got "
                                           f"{self.rcs_dbsm!r}"))
        return out


def _value(x):
    """The value of an Enum member, anything else unchanged."""
    return getattr(x, "value", x)


def _default_rcs() -> Dict[str, RcsConfig]:
    return {
        "default": RcsConfig(rcs_dbsm=10.0),
        "car": RcsConfig(rcs_dbsm=10.0),
        "truck": RcsConfig(rcs_dbsm=20.0, table="sensor/rcs/truck.csv"),
    }


class MergeMode(str, Enum):
    """How eq. 18's merge probability P_u decides a merge."""

    draw = "draw"              # one uniform draw per pair: merge with probability P_u
    threshold = "threshold"    # merge when P_u >= threshold


class Centroid(str, Enum):
    """Where a merged report sits: the plain or the power-weighted centroid of its ancestors."""

    plain = "plain"
    power = "power"


class MergeCells(str, Enum):
    """Which resolution cells two targets must share to be unresolved."""

    range_azimuth_range_rate = "range_azimuth_range_rate"   # a range-Doppler processor
    range_azimuth = "range_azimuth"                         # the paper's eq. 18 without Doppler


@dataclass
class MergeConfig:
    """Merging of close targets in one dwell (paper eq. 18, DESIGN §5.6).

    P_u = exp(-1/2 d^T R_u^-1 d), R_u = A / (2 ln 2), A = diag(cell^2): P_u = 1/2 one resolution
    cell apart (range cell Δr, azimuth cell = the dwell's beamwidth, range-rate cell λΔf_D/2).
    ``cells``: by default d includes the range rate (targets in different Doppler cells are
    resolved, as by any range-Doppler processor); ``range_azimuth`` leaves it out.
    """

    enabled: bool = True
    mode: MergeMode = MergeMode.draw
    threshold: float = 0.5
    cells: MergeCells = MergeCells.range_azimuth_range_rate
    centroid: Centroid = Centroid.plain

    @property
    def use_range_rate(self) -> bool:
        return _value(self.cells) == MergeCells.range_azimuth_range_rate.value

    def problems(self) -> List[Problem]:
        return schema.in_range(self, "threshold", 0.0, 1.0, lo_open=True)


def _freq_problems(freq_hz) -> List[Problem]:
    """``freq_hz`` outside :data:`FREQ_RANGE_HZ` (when it is a positive number at all: the
    positivity check names it otherwise), with the GHz reading when that one is in range."""
    lo, hi = FREQ_RANGE_HZ
    if not (isinstance(freq_hz, (int, float)) and math.isfinite(freq_hz) and freq_hz > 0) \
            or lo <= freq_hz <= hi:
        return []
    hint = ""
    if lo <= freq_hz * 1e9 <= hi:
        hint = f"; in hertz: {freq_hz:g} GHz = {freq_hz * 1e9:g}"
    return [Problem("freq_hz", f"must be a radar carrier frequency in [{lo:g}, {hi:g}] Hz "
                               f"(VHF to millimetre wave; GMTI radars use ~0.4-35 GHz, X band "
                               f"10e9), got {freq_hz!r}{hint}")]


@dataclass
class SensorConfig:
    """One airborne GMTI radar (paper Table 1 with DESIGN §5's corrections).

    Defaults are a plausible X-band side-looking airborne GMTI (the ``default`` preset).

    Not ``frozen``: OmegaConf 2.3 marks frozen dataclass nodes read-only, and then a nested
    override (``sensor.peak_power_w=...`` inside the app config, or any ``rcs.<type>`` entry)
    fails at compose time.  Treat instances as immutable (use ``dataclasses.replace``).
    """

    # --- transmitter / receiver (radar equation, DESIGN §5.3) --------------------------------
    freq_hz: float = 10.0e9                 # carrier frequency ν (λ = c/ν)
    peak_power_w: float = 500.0             # P_S, peak transmit power
    pulse_width_s: float = 5.0e-6           # τ, uncompressed pulse duration
    pri_s: Optional[float] = 250.0e-6       # PRI; None = no ambiguity, no blind speeds
    cpi_s: float = 0.032                    # coherent processing interval (per dwell)
    bandwidth_hz: float = 50.0e6            # B, waveform bandwidth (range resolution c/2B)
    noise_figure_db: float = 4.0            # F
    system_temp_k: float = 290.0            # T_0
    losses_db: float = 12.0                 # L, total system and processing losses
    integration_gain_db: Optional[float] = None  # G_I; None = CPI/PRI (needs pri_s)

    # --- antenna (eq. 7-9) ------------------------------------------------------------------
    n_elements: int = 1000                  # N, array elements
    aperture_m: float = 1.2                 # d_a, horizontal aperture
    beamwidth_factor: float = 1.0           # k in BW = k λ / d_a
    mount_deg: float = 90.0                 # φ_d, boresight vs flight direction; 90 = right
    stap: bool = True                       # apply the STAP clutter notch (eq. 10)
    mdv_mps: Any = 2.0                      # v_MDV (m/s), or "auto": from v_p, λ, d_a, scan

    # --- field of view (antenna frame) and scan ---------------------------------------------
    az_min_deg: float = -10.0               # scan sector, + clockwise from boresight
    az_max_deg: float = 10.0
    el_min_deg: float = -30.0               # elevation limits in the rolled antenna frame
    el_max_deg: float = -3.0
    range_min_m: float = 20_000.0           # slant range limits
    range_max_m: float = 36_000.0
    revisit_s: float = 5.0                  # time between scan starts
    dwell_spacing_beamwidths: float = 1.0   # beam-centre spacing, in (sine-space) beamwidths
    footprint_beamwidths: float = 1.0       # pair a target with beams this close (sine space)

    # --- detection (eq. 6, 11) --------------------------------------------------------------
    pfa: float = 1.0e-6                     # false-alarm probability per resolution cell
    noise_false_alarms: bool = True         # draw the detector's thermal-noise false alarms
    max_false_alarms_per_dwell: float = 1.0e5   # refuse P_FA x cells above this (memory guard)
    horizon_k_factor: float = 4.0 / 3.0     # effective earth radius factor of the radar horizon
    snr_form: str = "radar_equation"        # radar_equation | reference
    snr0_db: float = 20.0                   # reference form: SNR_0 at R_0 for σ_0
    r0_m: float = 30_000.0
    rcs0_dbsm: float = 10.0

    # --- measurement errors (eq. 12-17, DESIGN §5.5 floors) ----------------------------------
    gamma_az: float = 0.44                  # ≈ 1/(1.6 √2), monopulse
    gamma_r: float = 0.71                   # ≈ 1/√2
    gamma_rr: float = 0.71
    kappa_az: float = 1.0                   # floor κ BW/10, κ typically 1..2
    kappa_r: float = 1.0
    kappa_rr: float = 1.0
    range_resolution_factor: float = 1.0    # k in Δr = k c / 2B
    k_d: float = 1.0                        # k_D in Δf_D = k_D / CPI

    # --- radar cross sections ---------------------------------------------------------------
    rcs: Dict[str, RcsConfig] = field(default_factory=_default_rcs)

    # --- merging of close targets (eq. 18; gmtiflow.sensor.effects.Merging) ------------------
    merge: MergeConfig = field(default_factory=MergeConfig)

    # --- derived quantities -----------------------------------------------------------------
    @property
    def wavelength_m(self) -> float:
        return C_MPS / self.freq_hz

    @property
    def beamwidth_sine(self) -> float:
        """Broadside 3-dB beamwidth k λ / d_a, in sine space (= radians at broadside)."""
        return self.beamwidth_factor * self.wavelength_m / self.aperture_m

    @property
    def n_dwells(self) -> int:
        """Beam positions (dwells) per scan: the sector in sine space over the dwell spacing
        (docs/sensor.md "Scan"; :mod:`gmtiflow.sensor.scan` lays them out)."""
        span = math.sin(math.radians(self.az_max_deg)) - math.sin(math.radians(self.az_min_deg))
        step = self.dwell_spacing_beamwidths * self.beamwidth_sine
        return max(1, math.ceil(span / step - 1e-9))

    @property
    def range_resolution_m(self) -> float:
        """Δr = k c / (2B)."""
        return self.range_resolution_factor * C_MPS / (2.0 * self.bandwidth_hz)

    @property
    def doppler_cell_hz(self) -> float:
        """Δf_D = k_D / CPI."""
        return self.k_d / self.cpi_s

    @property
    def mdv_auto(self) -> bool:
        """``mdv_mps: auto``: the notch width follows the main-lobe clutter spread per dwell."""
        return isinstance(self.mdv_mps, str) and self.mdv_mps == "auto"

    @property
    def blind_speed_mps(self) -> Optional[float]:
        """First blind speed λ·PRF/2 (the notch repeats with this period); None without PRI."""
        return None if self.pri_s is None else self.wavelength_m / (2.0 * self.pri_s)

    @property
    def wrap_velocity_mps(self) -> float:
        """Unambiguous range-rate half-interval λ·PRF/4; NaN without PRI."""
        return math.nan if self.pri_s is None else self.wavelength_m / (4.0 * self.pri_s)

    @property
    def integration_gain(self) -> float:
        """G_I (linear): the configured value, else CPI/PRI (number of pulses).

        ``pri_s: null`` needs ``integration_gain_db`` (``problems()`` refuses it otherwise), so
        the gain is never silently 1."""
        if self.integration_gain_db is not None:
            return 10.0 ** (self.integration_gain_db / 10.0)
        if self.pri_s is None:
            raise ValueError("sensor.pri_s is null: set sensor.integration_gain_db")
        return self.cpi_s / self.pri_s

    @property
    def doppler_band_hz(self) -> float:
        """Width of the Doppler band the detector searches: the PRF, or without a PRI the
        equivalent G_I / CPI (one Doppler filter per integrated pulse)."""
        if self.pri_s is not None:
            return 1.0 / self.pri_s
        return self.integration_gain / self.cpi_s

    @property
    def range_rate_band_mps(self) -> float:
        """Half-width of the range-rate interval the Doppler band covers, λ·band/4 (m/s):
        λ·PRF/4, the wrap velocity, with a PRI."""
        return self.wavelength_m * self.doppler_band_hz / 4.0

    @property
    def noise_cells(self) -> tuple:
        """(range, Doppler, angle) resolution cells the detector tests in one dwell.

        Range: the slant-range window [range_min_m, range_max_m] (cut at the unambiguous range
        c·PRI/2 with a PRI) over Δr.  Doppler: the searched band over Δf_D (PRF·CPI/k_D, the
        number of pulses with k_D = 1).  Angle: 1, the dwell's beam (monopulse refines a
        detection's angle inside its beam; it does not test separate angle cells)."""
        r_hi = self.range_max_m
        if self.pri_s is not None:
            r_hi = min(r_hi, C_MPS * self.pri_s / 2.0)
        n_range = max(r_hi - self.range_min_m, 0.0) / self.range_resolution_m
        n_doppler = self.doppler_band_hz / self.doppler_cell_hz
        return n_range, n_doppler, 1.0

    @property
    def expected_false_alarms_per_dwell(self) -> float:
        """P_FA × range cells × Doppler cells × angle cells (before masks)."""
        n_r, n_d, n_a = self.noise_cells
        return self.pfa * n_r * n_d * n_a

    def normalised(self) -> "SensorConfig":
        """A copy with ``snr_form`` as a plain string (an Enum is accepted by its value)."""
        return replace(self, snr_form=_value(self.snr_form))

    # --- validation -------------------------------------------------------------------------
    def problems(self) -> List[Problem]:
        """Range and cross-field checks (keys relative to the sensor group)."""
        p: List[Problem] = []
        p += schema.positive(self, "freq_hz", "peak_power_w", "pulse_width_s", "pri_s", "cpi_s",
                             "bandwidth_hz", "system_temp_k", "aperture_m", "beamwidth_factor",
                             "revisit_s", "dwell_spacing_beamwidths", "footprint_beamwidths",
                             "r0_m", "gamma_az", "gamma_r", "gamma_rr",
                             "kappa_az", "kappa_r", "kappa_rr", "range_resolution_factor", "k_d")
        p += schema.non_negative(self, "noise_figure_db", "losses_db", "range_min_m")
        if isinstance(self.mdv_mps, str):
            if self.mdv_mps != "auto":
                p.append(Problem("mdv_mps", f"must be a number of m/s or 'auto', got "
                                            f"{self.mdv_mps!r}"))
        else:
            p += schema.non_negative(self, "mdv_mps")
        p += schema.positive(self, "range_max_m")
        if not (isinstance(self.n_elements, int) and not isinstance(self.n_elements, bool)
                and self.n_elements >= 1):
            p.append(Problem("n_elements", f"must be an integer >= 1, got {self.n_elements!r}"))
        for name in ("integration_gain_db", "snr0_db", "rcs0_dbsm", "mount_deg"):
            value = getattr(self, name)
            if value is not None and not (isinstance(value, (int, float)) and math.isfinite(value)):
                p.append(Problem(name, f"must be a finite number, got {value!r}"))
        p += schema.in_range(self, "mount_deg", -180.0, 180.0)
        p += schema.in_range(self, "az_min_deg", -89.0, 89.0)
        p += schema.in_range(self, "az_max_deg", -89.0, 89.0)
        p += schema.in_range(self, "el_min_deg", -90.0, 90.0)
        p += schema.in_range(self, "el_max_deg", -90.0, 90.0)
        p += schema.in_range(self, "pfa", 0.0, 1.0, lo_open=True, hi_open=True)
        p += schema.positive(self, "max_false_alarms_per_dwell", "horizon_k_factor")
        if self.pri_s is None and self.integration_gain_db is None:
            p.append(Problem("integration_gain_db", "must be set when pri_s is null (without a "
                                                    "PRI the number of integrated pulses "
                                                    "CPI/PRI is unknown)"))
        p += schema.ordered(self, "az_min_deg", "az_max_deg", strict=False)
        p += schema.ordered(self, "el_min_deg", "el_max_deg")
        p += schema.ordered(self, "range_min_m", "range_max_m")
        if _value(self.snr_form) not in SNR_FORMS:
            p.append(Problem("snr_form", f"must be one of {', '.join(SNR_FORMS)}, got "
                                         f"{self.snr_form!r}"))
        p += _freq_problems(self.freq_hz)
        if p:  # the cross-field checks below need sane numbers
            return p
        if self.pri_s is not None:
            if self.pri_s <= self.pulse_width_s:
                p.append(Problem("pri_s", f"must be > pulse_width_s ({self.pulse_width_s!r}), "
                                          f"got {self.pri_s!r}"))
            if self.cpi_s < self.pri_s:
                p.append(Problem("cpi_s", f"must hold at least one PRI ({self.pri_s!r} s), got "
                                          f"{self.cpi_s!r}"))
        if self.pulse_width_s * self.bandwidth_hz < 1.0:
            p.append(Problem("bandwidth_hz", f"time-bandwidth product pulse_width_s * "
                                             f"bandwidth_hz must be >= 1, got "
                                             f"{self.pulse_width_s * self.bandwidth_hz!r}"))
        if self.beamwidth_sine >= 1.0:
            p.append(Problem("aperture_m", f"beamwidth k*lambda/d_a = {self.beamwidth_sine:.3g} "
                                           f"must be < 1 (aperture too small for the wavelength "
                                           f"lambda = c/freq_hz = {self.wavelength_m:.3g} m)"))
        if self.stap and not self.mdv_auto and self.mdv_mps <= 0:
            p.append(Problem("mdv_mps", f"must be > 0 when stap is true, got {self.mdv_mps!r}"))
        if self.stap and not self.mdv_auto and self.blind_speed_mps is not None and \
                self.mdv_mps >= self.blind_speed_mps / 2.0:
            p.append(Problem("mdv_mps", f"must be < half the blind speed lambda*PRF/2 "
                                        f"({self.blind_speed_mps / 2.0:.4g} m/s), got "
                                        f"{self.mdv_mps!r}"))
        n_dwells = self.n_dwells
        scan_s = n_dwells * self.cpi_s
        if self.noise_false_alarms and \
                self.expected_false_alarms_per_dwell > self.max_false_alarms_per_dwell:
            n_r, n_d, _ = self.noise_cells
            p.append(Problem("pfa", f"gives {self.expected_false_alarms_per_dwell:.4g} noise "
                                    f"false alarms per dwell (P_FA {self.pfa!r} x {n_r:.4g} "
                                    f"range cells x {n_d:.4g} Doppler cells), more than "
                                    f"max_false_alarms_per_dwell = "
                                    f"{self.max_false_alarms_per_dwell!r}: narrow the range "
                                    "window, lower pfa or raise the limit"))
        if self.revisit_s < scan_s:
            p.append(Problem("revisit_s", f"must be >= the scan time n_dwells * cpi_s = "
                                          f"{n_dwells} * {self.cpi_s} = {scan_s:.4g} s, got "
                                          f"{self.revisit_s!r}"))
        if not self.rcs:
            p.append(Problem("rcs", "needs at least one vehicle type (or 'default')"))
        for name, model in self.rcs.items():
            p += schema.prefixed(f"rcs.{name}", model.problems())
        return p
