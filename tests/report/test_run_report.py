"""The run report PDF: pages, edge cases, rendering, animation, config."""
import pytest

from gmtiflow.errors import StoreError
from gmtiflow.report import ReportConfig, build_run_report
from gmtiflow.report.run_report import PAGES

from .conftest import page_count, pixel_std, render_png


def test_report_has_all_pages_and_renders_non_blank(small_run, tmp_path):
    out = build_run_report(ReportConfig(), small_run, tmp_path / "report.pdf")
    assert out == tmp_path / "report.pdf" and out.stat().st_size > 10_000
    assert page_count(out) == len(PAGES) == 7
    assert not list(tmp_path.glob(".*partial*"))
    pngs = render_png(out, tmp_path / "page", 1, 3)
    assert len(pngs) == 3
    for png in pngs:
        assert pixel_std(png) > 0.05, f"{png.name} looks blank"


@pytest.mark.parametrize("fixture", ["clutter_run", "empty_run"])
def test_report_on_runs_without_tracker_or_detections(fixture, request, tmp_path):
    run = request.getfixturevalue(fixture)
    out = build_run_report(ReportConfig(), run, tmp_path / "r.pdf")
    assert page_count(out) == 7


def test_missing_run_file_is_a_clear_error_and_leaves_nothing(tmp_path):
    with pytest.raises(StoreError, match="no such run file"):
        build_run_report(ReportConfig(), tmp_path / "run.h5", tmp_path / "report.pdf")
    assert not list(tmp_path.iterdir())


def test_report_freezes_the_collector_only_when_nobody_else_has(small_run, tmp_path):
    """build_run_report freezes the objects alive before it and unfreezes them on exit, even
    on error; inside a caller's freeze (gmtiflow.pipeline.run) it leaves that freeze alone."""
    import gc
    assert gc.get_freeze_count() == 0
    build_run_report(ReportConfig(), small_run, tmp_path / "a.pdf")
    assert gc.get_freeze_count() == 0
    with pytest.raises(StoreError):
        build_run_report(ReportConfig(), tmp_path / "missing.h5", tmp_path / "b.pdf")
    assert gc.get_freeze_count() == 0
    gc.freeze()
    try:
        frozen = gc.get_freeze_count()
        build_run_report(ReportConfig(), small_run, tmp_path / "c.pdf")
        assert gc.get_freeze_count() > frozen - 100 > 0    # (a few frozen objects died)
    finally:
        gc.unfreeze()


@pytest.mark.slow
def test_animation_gif(small_run, tmp_path):
    cfg = ReportConfig(animation=True, animation_max_frames=3)
    out = build_run_report(cfg, small_run, tmp_path / "report.pdf")
    gif = out.with_suffix(".gif")
    assert gif.is_file() and gif.read_bytes()[:6] in (b"GIF89a", b"GIF87a")


def test_report_config_group_and_validation(tmp_path):
    from gmtiflow.compose import compose
    from gmtiflow.errors import ConfigError
    for option, enabled in (("default", True), ("none", False)):
        app = compose([f"report={option}"])
        assert isinstance(app.report, ReportConfig) and app.report.enabled is enabled
    with pytest.raises(ConfigError, match="report.filename.*report.max_points|report.max_points.*report.filename"):
        compose(["report.filename=out.png", "report.max_points=0"])


def test_lazy_tables_read_what_read_table_reads_and_only_when_asked(small_run, tmp_path):
    import shutil

    import numpy as np

    from gmtiflow.report.data import load_run
    copy = tmp_path / "run.h5"
    shutil.copy(small_run, copy)
    eager, lazy = load_run(copy), load_run(copy, lazy=True)
    assert set(eager.tables) == set(lazy.tables)
    for name, table in eager.tables.items():
        assert list(lazy.table(name)) == list(table) and "nosuch" not in lazy.table(name)
        for column, values in table.items():
            got = lazy.table(name)[column]
            assert got.dtype == values.dtype
            assert np.array_equal(got, values, equal_nan=got.dtype.kind == "f")
    truth = load_run(copy, lazy=True).table("truth")
    x_m = truth["x_m"]                         # read now, kept
    copy.unlink()
    assert truth["x_m"] is x_m and truth.get("nosuch") is None
    with pytest.raises(StoreError, match="run.h5"):
        truth["y_m"]                           # never read, and the file is gone
    with pytest.raises(StoreError, match="no column 'nosuch'"):
        truth["nosuch"]


def test_load_run_reads_and_checks_the_config_once(small_run, monkeypatch):
    """open_run checks /config (a YAML parse); load_run reuses that parse instead of reading
    and checking the text again (it did both: three parses of the same YAML per report)."""
    import yaml

    from gmtiflow import store
    from gmtiflow.report.data import load_run
    expected = yaml.safe_load(store.read_text(small_run, "config"))
    calls = []
    real = store.yaml.load
    monkeypatch.setattr(store, "_LAST_PARSED", {})    # not parsed earlier in this process
    monkeypatch.setattr(store.yaml, "load",
                        lambda text, Loader: calls.append(1) or real(text, Loader=Loader))
    run = load_run(small_run, lazy=True)
    assert len(calls) == 1
    assert run.config == expected and run.cfg("scene.duration_s") == 30
