"""Ctrl-C stops a run even when the KeyboardInterrupt is swallowed by an extension."""
import signal
import threading

import pytest

from gmtiflow import interrupts, pipeline
from gmtiflow.compose import compose


@pytest.fixture
def fresh_request(monkeypatch):
    monkeypatch.setattr(interrupts, "_requested", threading.Event())
    previous = signal.getsignal(signal.SIGINT)
    yield
    signal.signal(signal.SIGINT, previous)


def test_a_swallowed_ctrl_c_stops_the_run_before_the_run_file_is_committed(tmp_path,
                                                                          fresh_request):
    try:
        interrupts._on_sigint(signal.SIGINT, None)
    except KeyboardInterrupt:
        pass                        # what C code that clears pending exceptions does
    cfg = compose(["scene.duration_s=10", "report=none", "export=none", "tracker=none",
                   "cache.enabled=false", "progress=false"])
    with pytest.raises(KeyboardInterrupt):
        pipeline.run(cfg, tmp_path)
    assert not (tmp_path / pipeline.RUN_FILE).exists()
    assert not list(tmp_path.glob(".run.h5.*"))


def test_install_keeps_an_ignored_sigint_ignored(fresh_request):
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    interrupts.install()
    assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    signal.signal(signal.SIGINT, signal.default_int_handler)
    interrupts.install()
    assert signal.getsignal(signal.SIGINT) is interrupts._on_sigint
    assert not interrupts.requested()
    with pytest.raises(KeyboardInterrupt):
        signal.raise_signal(signal.SIGINT)
    assert interrupts.requested()


def test_an_interrupt_while_the_run_file_is_created_leaves_no_partial_file(tmp_path):
    """Ctrl-C can land inside RunWriter's constructor, after the temporary file exists and
    before ``with`` would clean up (seen once in test_rundir's Ctrl-C test)."""
    from gmtiflow import store

    class Boom:                     # the seed attribute is written after the file is created
        def __int__(self):
            raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt):
        store.RunWriter(tmp_path / "run.h5", seed=Boom())
    assert not list(tmp_path.iterdir())
