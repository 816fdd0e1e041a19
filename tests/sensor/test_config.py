"""SensorConfig: presets load into valid configs; problems() catches bad values."""
from dataclasses import asdict, replace
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from gmtiflow.sensor import scan
from gmtiflow.sensor.config import RcsConfig, SensorConfig

CONF = Path(__file__).resolve().parents[2] / "conf" / "sensor"


def load(name):
    base = OmegaConf.structured(SensorConfig)
    return OmegaConf.to_object(OmegaConf.merge(base, OmegaConf.load(CONF / f"{name}.yaml")))


@pytest.mark.parametrize("name", ["default", "wide_fov", "no_stap"])
def test_presets_load_and_are_valid(name):
    cfg = load(name)
    assert isinstance(cfg, SensorConfig)
    assert cfg.problems() == []


def test_default_preset_equals_dataclass_defaults():
    assert asdict(load("default")) == asdict(SensorConfig())


def test_presets_hold_only_dataclass_fields():
    fields = set(asdict(SensorConfig()))
    for path in CONF.glob("*.yaml"):
        assert set(OmegaConf.load(path)) <= fields, path.name


def keys(cfg):
    return {p.key for p in cfg.problems()}


@pytest.mark.parametrize("change, key", [
    (dict(peak_power_w=-1.0), "peak_power_w"),
    (dict(freq_hz=0.0), "freq_hz"),
    (dict(az_min_deg=20.0, az_max_deg=10.0), "az_min_deg"),
    (dict(el_min_deg=-2.0, el_max_deg=-3.0), "el_min_deg"),
    (dict(range_min_m=40_000.0), "range_min_m"),
    (dict(pri_s=1e-6, pulse_width_s=5e-6), "pri_s"),
    (dict(revisit_s=0.1), "revisit_s"),
    (dict(pfa=0.0), "pfa"),
    (dict(pfa=1.0), "pfa"),
    (dict(snr_form="magic"), "snr_form"),
    (dict(az_max_deg=90.0), "az_max_deg"),
    (dict(n_elements=0), "n_elements"),
    (dict(mdv_mps=40.0), "mdv_mps"),
    (dict(cpi_s=1e-4), "cpi_s"),
    (dict(rcs={"car": RcsConfig(rcs_dbsm=float("nan"))}), "rcs.car.rcs_dbsm"),
])
def test_problems_name_the_bad_key(change, key):
    assert key in keys(replace(SensorConfig(), **change))


def test_no_pri_is_allowed_and_has_no_wrap():
    cfg = SensorConfig(pri_s=None, integration_gain_db=21.0)
    assert cfg.problems() == []
    assert cfg.blind_speed_mps is None
    assert cfg.wrap_velocity_mps != cfg.wrap_velocity_mps  # NaN
    assert cfg.integration_gain == pytest.approx(10 ** 2.1)


def test_derived_quantities():
    cfg = SensorConfig()
    assert cfg.wavelength_m == pytest.approx(0.0299792458)
    assert cfg.range_resolution_m == pytest.approx(299792458 / 1e8)
    assert cfg.integration_gain == pytest.approx(128.0)
    assert cfg.blind_speed_mps == pytest.approx(cfg.wavelength_m * 4000 / 2)


def test_an_unknown_dwell_mode_is_refused_by_the_schedule():
    with pytest.raises(ValueError, match="dwell_mode"):
        scan.build_schedule(SensorConfig(), 10.0, "fast")


@pytest.mark.parametrize("freq_hz", [10.0, 1e6, 2e7, 1e12, 3.1e11])
def test_a_carrier_frequency_outside_radar_bands_is_refused_by_its_own_key(freq_hz):
    # sensor.freq_hz=10 (GHz meant) used to be blamed on aperture_m (the beamwidth λ/d_a > 1)
    problems = replace(SensorConfig(), freq_hz=freq_hz).problems()
    assert [p.key for p in problems] == ["freq_hz"]
    assert "3e+07" in problems[0].message and "3e+11" in problems[0].message


def test_a_frequency_given_in_ghz_gets_a_hint():
    (problem,) = replace(SensorConfig(), freq_hz=10.0).problems()
    assert "10 GHz = 1e+10" in problem.message


@pytest.mark.parametrize("freq_hz", [3e7, 4.5e8, 1e10, 3.5e10, 3e11])
def test_carrier_frequencies_of_radar_bands_are_accepted(freq_hz):
    # the other settings follow the band (VHF needs a wider aperture than 1.2 m, mm-wave a
    # longer revisit): only freq_hz itself is checked here
    assert "freq_hz" not in keys(replace(SensorConfig(), freq_hz=freq_hz, aperture_m=12.0))
