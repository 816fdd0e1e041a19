"""/config text: ``config.to_yaml`` writes what OmegaConf's structured round trip writes."""
import pytest
from omegaconf import OmegaConf

from gmtiflow import config
from gmtiflow.compose import compose
from gmtiflow.scene.vehicles import VehicleSpec, VehiclesConfig


@pytest.mark.parametrize("overrides", [[], ["experiment=two_orbits"],
                                       ["experiment=challenge/offroad", "fidelity=fast"]])
def test_to_yaml_is_omegaconfs_text(overrides):
    cfg = compose(overrides)
    assert config.to_yaml(cfg) == OmegaConf.to_yaml(OmegaConf.structured(cfg))


def test_to_yaml_of_listed_vehicles_and_enums():
    cfg = compose(["fidelity=full"])
    cfg.vehicles = VehiclesConfig(vehicles=[
        VehicleSpec(name=f"v{i}", off_road=[[0.0, 0.0], [100.0 * i + 1, 5.0]]) for i in range(5)])
    text = config.to_yaml(cfg)
    assert text == OmegaConf.to_yaml(OmegaConf.structured(cfg))
    assert "dwell_mode: dwell_resolved" in text and "name: v4" in text


def test_to_yaml_quotes_and_wraps_as_omegaconf_does():
    # to_yaml emits with libyaml (when PyYAML has it), OmegaConf with the pure-Python emitter:
    # names that read as bools or numbers, non-ASCII, long and odd strings, tiny and huge floats.
    cfg = compose([])
    names = ["yes", "1.5", "10", "1e5", "null", "~", "héllo ✓", "a: b", "#c", " lead", "'q'",
             "x" * 200, "word " * 40]
    cfg.vehicles = VehiclesConfig(vehicles=[
        VehicleSpec(name=n, off_road=[[1e-300, -0.0], [1e300, 123456789.123456789]])
        for n in names])
    text = config.to_yaml(cfg)
    assert text == OmegaConf.to_yaml(OmegaConf.structured(cfg))
    assert "name: 'yes'" in text and "name: héllo ✓" in text
