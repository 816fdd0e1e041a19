"""No tool writes over its own input (issue 17, item 1): same path, symlink or hard link."""
from __future__ import annotations

import os

import pytest

from gmtiflow import convert, store
from gmtiflow.evaluate import cli as evaluate_cli
from gmtiflow.report import cli as report_cli


def _alias(run, kind):
    if kind == "same":
        return run
    alias = run.parent / f"alias_{kind}.csv"
    if kind == "symlink":
        alias.symlink_to(run)
    elif kind == "hardlink":
        os.link(run, alias)
    elif kind == "dotdot":
        alias = run.parent / ".." / run.parent.name / run.name
    return alias


@pytest.mark.parametrize("kind", ["same", "symlink", "hardlink", "dotdot"])
def test_convert_refuses_an_output_that_is_its_input(run_copy, capsys, kind):
    run = run_copy / "run.h5"
    before = run.read_bytes()
    out = _alias(run, kind)
    code = convert.main([str(run), "--to", "csv", "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 1 and "would overwrite the input" in err, err
    assert run.read_bytes() == before
    with store.open_run(run):
        pass


@pytest.mark.parametrize("kind", ["same", "hardlink"])
def test_convert_back_to_h5_refuses_its_input(run_copy, capsys, kind):
    csv = run_copy / "detections.csv"
    before = csv.read_bytes()
    out = csv if kind == "same" else run_copy / "link.h5"
    if kind == "hardlink":
        os.link(csv, out)
    code = convert.main([str(csv), "--to", "h5", "-o", str(out)])
    assert code == 1 and "would overwrite the input" in capsys.readouterr().err
    assert csv.read_bytes() == before


@pytest.mark.parametrize("kind", ["symlink", "hardlink"])
def test_evaluate_refuses_an_output_that_is_the_run_file(run_copy, capsys, kind):
    run = run_copy / "run.h5"
    before = run.read_bytes()
    out = _alias(run, kind)
    code = evaluate_cli.main([str(run_copy / "tracks.csv"), str(run), "-o", str(out)])
    assert code == 1 and "would overwrite the input" in capsys.readouterr().err
    assert run.read_bytes() == before


def test_report_refuses_an_output_that_is_a_run_file(run_copy, capsys):
    run = run_copy / "run.h5"
    before = run.read_bytes()
    code = report_cli.main([str(run_copy), "-q", "-o", str(run)])
    assert code == 1 and "would overwrite the input" in capsys.readouterr().err
    assert run.read_bytes() == before
