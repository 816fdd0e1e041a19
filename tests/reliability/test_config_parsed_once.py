"""A run's /config is parsed once per process while its text is the same (store._parse_config):
the exports, the report and the command's summary each open the run file, and a config listing
1,000 vehicles takes ~0.5 s to parse.  A changed or refused text is parsed (and checked) anew."""
from __future__ import annotations

import h5py
import pytest
import yaml

from gmtiflow import store
from gmtiflow.errors import StoreError


@pytest.fixture
def yaml_loads(monkeypatch):
    """The texts ``yaml.load`` parses from here on."""
    texts = []
    real = yaml.load

    def counting(stream, Loader):
        texts.append(stream)
        return real(stream, Loader=Loader)
    monkeypatch.setattr(store.yaml, "load", counting)
    monkeypatch.setattr(store, "_LAST_PARSED", {})
    return texts


def _set_config(path, text: str) -> None:
    with h5py.File(path, "r+") as f:
        del f["config"]
        f["config"] = text


def test_reopening_a_run_parses_its_config_once(run_copy, yaml_loads):
    path = run_copy / "run.h5"
    with store.open_run(path) as f:
        first = store.read_config(f)
    with store.open_run(path) as f:
        second = store.read_config(f)
    assert len(yaml_loads) == 1
    assert second is first and first["seed"] is not None


def test_a_changed_config_is_parsed_and_checked_again(run_copy, yaml_loads):
    path = run_copy / "run.h5"
    with store.open_run(path) as f:
        text = store.read_text(f, "config", check=False)
        before = store.read_config(f)
    _set_config(path, text.replace("seed: ", "seed: 1", 1))
    with store.open_run(path) as f:
        after = store.read_config(f)
    assert len(yaml_loads) == 2
    assert after["seed"] != before["seed"]
    _set_config(path, text + "\nsneaky: ${oc.env:HOME}\n")
    for _ in range(2):      # refused each time: a refused text is never kept
        with pytest.raises(StoreError, match="interpolation"):
            store.open_run(path)
    assert len(yaml_loads) == 4
    _set_config(path, text)     # the first text again: the last kept was the changed one
    with store.open_run(path) as f:
        assert store.read_config(f) == before
    assert len(yaml_loads) == 5
