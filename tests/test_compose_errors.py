"""Hydra's composition errors through the Python API: one-line ConfigErrors (the CLI's are in
tests/test_cli.py)."""
import pytest

from gmtiflow.compose import compose
from gmtiflow.errors import CompositionError, ConfigError


@pytest.mark.parametrize("override, message, hint", [
    ("sensor=wide_fvo", "config group sensor has no option 'wide_fvo'; did you mean "
                        "sensor=wide_fov? (options: default, no_stap, wide_fov)", None),
    ("platform.speed_mpss=3", "invalid config: platform.speed_mpss: unknown config key; did you "
                              "mean platform.speed_mps?", "gmtiflow --cfg job"),
    ("scene.duration_s=abc", "invalid config: scene.duration_s: Value 'abc' of type 'str' could "
                             "not be converted to Float", None),
    ("scene.duration_s=[1", "cannot parse the override 'scene.duration_s=[1': ", "KEY=VALUE"),
])
def test_compose_raises_one_line_config_errors(override, message, hint):
    with pytest.raises(CompositionError) as err:
        compose([override])
    assert isinstance(err.value, ConfigError)
    assert str(err.value).startswith(message) and "\n" not in str(err.value)
    if hint is None:
        assert err.value.hint is None
    else:
        assert hint in err.value.hint and "\n" not in err.value.hint


def test_other_exceptions_are_not_composition_errors():
    from gmtiflow.compose_errors import composition_error
    assert composition_error(ValueError("a bug")) is None      # raised outside Hydra
    assert composition_error(KeyError("x")) is None
