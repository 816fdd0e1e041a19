"""The newer entry points against the same fault classes (issue 17, "go beyond the list"):
gmtiflow-view, gmtiflow-bench, tracker import paths.  Each case found by
``benchmarks/reliability_table.py`` gives one clean error (exit 1 or 2, one line, no
traceback) and never overwrites an input."""
from __future__ import annotations

import hashlib
import sys

import pytest

from gmtiflow.errors import ConfigError, GmtiflowError
from gmtiflow.evaluate import protocol


def _digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


# ------------------------------------------------------------------------- gmtiflow-view
def test_view_refuses_to_write_over_its_run_file(run_copy, capsys):
    """``gmtiflow-view RUN -o RUN/run.h5`` used to replace the run file by the HTML page and
    exit 0 (data loss); a symlink to it is the same file."""
    from gmtiflow.report import viewer
    run_h5 = run_copy / "run.h5"
    before = _digest(run_h5)
    (run_copy / "alias.html").symlink_to(run_h5)
    for out in (run_h5, run_copy / "alias.html"):
        assert viewer.main([str(run_copy), "-o", str(out)]) == 1
        err = capsys.readouterr().err
        assert "would overwrite the input" in err and "Traceback" not in err
    assert _digest(run_h5) == before


def test_view_into_a_directory_is_one_clean_error(run_copy, tmp_path, capsys):
    """``-o`` naming a directory used to end in a raw IsADirectoryError."""
    from gmtiflow.report import viewer
    (tmp_path / "d").mkdir()
    assert viewer.main([str(run_copy), "-o", str(tmp_path / "d")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is a directory" in err and "Traceback" not in err


# ------------------------------------------------------------------------ gmtiflow-bench
@pytest.mark.parametrize("args, needle", [
    (["--jobs", "0"], "--jobs must be at least 1, got 0"),
    (["--jobs", "-3"], "--jobs must be at least 1"),
    (["--timeout", "-1"], "--timeout must be a finite number of seconds > 0"),
    (["--timeout", "nan"], "--timeout must be a finite number of seconds > 0, got nan"),
    (["report", "--timeout", "inf", "."], "--timeout must be a finite number"),
])
def test_bench_refuses_nonsense_numbers_before_any_sweep(args, needle, capsys, monkeypatch):
    """They used to go straight into the sweep (joblib n_jobs=0 fails inside Hydra's
    launcher after the jobs were composed)."""
    from gmtiflow.bench import cli
    monkeypatch.setattr(cli.subprocess, "run", lambda *a, **k: pytest.fail("a sweep started"))
    with pytest.raises(SystemExit) as info:
        cli.main(args)
    assert info.value.code == 2
    assert needle in capsys.readouterr().err


# ---------------------------------------------------------------- tracker import paths
@pytest.fixture
def user_modules(tmp_path, monkeypatch):
    (tmp_path / "raises_at_import.py").write_text("raise ZeroDivisionError('boom at import')\n")
    (tmp_path / "does_not_compile.py").write_text("class T:\n    x = (\n")
    (tmp_path / "lazy_attr.py").write_text(
        "def __getattr__(name):\n    raise RuntimeError('no ' + name)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    yield tmp_path
    for name in ("raises_at_import", "does_not_compile", "lazy_attr"):
        sys.modules.pop(name, None)


@pytest.mark.parametrize("target, needle", [
    ("raises_at_import.T", "importing module 'raises_at_import' raised ZeroDivisionError: "
                           "boom at import"),
    ("does_not_compile.T", "module 'does_not_compile' has a syntax error"),
    ("lazy_attr.T", "reading 'T' of module 'lazy_attr' raised RuntimeError: no T"),
])
def test_a_tracker_module_that_fails_to_import_is_a_clean_error(user_modules, target, needle):
    """`tracker=python tracker.target=<module>.T` with the user's module raising at import
    (or not compiling) used to end the run with the raw exception and Hydra's hint."""
    with pytest.raises(GmtiflowError) as info:
        protocol.load_tracker(target)
    assert needle in str(info.value) and "tracker.target" in str(info.value)


@pytest.mark.parametrize("target", ["", "math", "math.pi", "no_such_module_xyz.T", "json.loads"])
def test_tracker_targets_that_are_not_trackers_are_config_errors(target):
    with pytest.raises(ConfigError, match=r"tracker\.(target|params)"):
        protocol.load_tracker(target)



# ------------------------------------------------------------ gmtiflow-convert udp:// tcp://
@pytest.mark.parametrize("args, needle", [
    (["udp://:70000"], "udp://:70000: Port out of range"),
    (["udp://:47123", "--idle-timeout", "-1"], "--idle-timeout must be a finite number"),
    (["udp://:47123", "--idle-timeout", "nan"], "--idle-timeout must be a finite number"),
    (["udp://:47123", "--max-packets", "0"], "--max-packets must be at least 1, got 0"),
])
def test_live_receiver_options_are_checked_and_named(args, needle, tmp_path, capsys):
    """A port out of range used to be reported without the address; a negative or NaN idle
    timeout as socket's "Timeout value out of range" / "Invalid value NaN"; --max-packets 0
    listened for the whole idle timeout and then blamed the sender."""
    from gmtiflow import convert
    code = convert.main([*args[:1], "--to", "h5", "-o", str(tmp_path / "x.h5"), *args[1:]])
    err = capsys.readouterr().err
    assert code == 1 and needle in err and "Traceback" not in err, err
    assert not (tmp_path / "x.h5").exists()
