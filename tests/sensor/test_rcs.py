"""RCS models: constants, periodic aspect tables, and clear errors for bad tables."""
import math

import numpy as np
import pytest

from gmtiflow.errors import ConfigError, InputFileError
from gmtiflow.sensor import rcs
from gmtiflow.sensor.config import RcsConfig, SensorConfig


def write(tmp_path, text, name="t.csv"):
    p = tmp_path / name
    p.write_text(text)
    return str(p)


def test_shipped_truck_table_loads_and_is_periodic():
    aspect, value = rcs.load_table("sensor/rcs/truck.csv")
    assert len(aspect) >= 2
    models = rcs.RcsModels.from_config(SensorConfig().rcs)
    code = models.type_codes(["truck"])[0]
    # a heading of 90° seen along a northward LOS: aspect 90° (broadside), the table's peak
    v = models.rcs_dbsm(np.array([code, code]), np.radians([90.0, 90.0 + 360.0]),
                        np.array([0.0, 0.0]), np.array([1.0, 1.0]))
    assert v[0] == pytest.approx(28.0) and v[1] == pytest.approx(28.0)


def test_interpolation_wraps_between_last_and_first_row(tmp_path):
    a, v = rcs.load_table(write(tmp_path, "aspect_deg,rcs_dbsm\n0,0\n90,10\n270,20\n"))
    got = rcs.interpolate(np.radians([0, 45, 315, 359.999, 180, -45]), a, v)
    assert got == pytest.approx([0, 5, 10, 0.0, 15, 10], abs=1e-3)


def test_aspect_angle_convention():
    # LOS to the north; a vehicle driving north is seen from behind: aspect 0
    assert rcs.aspect_rad(0.0, 0.0, 1.0) == pytest.approx(0.0)
    assert rcs.aspect_rad(math.pi, 0.0, 1.0) == pytest.approx(math.pi)
    assert rcs.aspect_rad(math.pi / 2, 0.0, 1.0) == pytest.approx(math.pi / 2)


def test_constant_models_and_default_entry():
    models = rcs.RcsModels.from_config({"default": RcsConfig(3.0), "car": RcsConfig(7.0)})
    codes = models.type_codes(["car", "bus"])
    assert list(models.rcs_dbsm(codes, np.zeros(2), np.zeros(2), np.ones(2))) == [7.0, 3.0]
    with pytest.raises(ConfigError, match="bus"):
        rcs.RcsModels.from_config({"car": RcsConfig(7.0)}).type_codes(["bus"])


@pytest.mark.parametrize("text, line, what", [
    ("aspect_deg,rcs_dbsm\n0,1\n10,x\n", 3, "non-numeric"),
    ("aspect_deg,rcs_dbsm\n0,1\n20,2\n10,3\n", 4, "unsorted"),
    ("aspect_deg,rcs_dbsm\n0,1\n0,2\n", 3, "duplicate"),
    ("aspect_deg,rcs_dbsm\n0,1\n360,2\n", 3, "360"),
    ("aspect_deg,rcs_dbsm\n-5,1\n10,2\n", 2, "-5"),
    ("angle,rcs\n0,1\n10,2\n", 1, "header"),
    ("aspect_deg,rcs_dbsm\n0,1,2\n10,2\n", 2, "2 values"),
])
def test_malformed_tables_name_file_and_line(tmp_path, text, line, what):
    path = write(tmp_path, text)
    with pytest.raises(InputFileError) as err:
        rcs.load_table(path)
    msg = str(err.value)
    assert "t.csv" in msg and f"line {line}" in msg and what in msg


def test_too_short_empty_and_missing_tables(tmp_path):
    with pytest.raises(InputFileError, match="at least 2 rows"):
        rcs.load_table(write(tmp_path, "aspect_deg,rcs_dbsm\n0,1\n"))
    with pytest.raises(InputFileError, match="empty"):
        rcs.load_table(write(tmp_path, "# nothing\n\n", "e.csv"))
    with pytest.raises(InputFileError, match="nope.csv"):
        rcs.load_table(str(tmp_path / "nope.csv"))


def test_a_table_saved_with_a_byte_order_mark_loads(tmp_path):
    """Spreadsheets save "CSV UTF-8" with a byte-order mark; the header then looked right to
    the user but was refused as "expected the header 'aspect_deg,rcs_dbsm', got (not shown)"."""
    t = tmp_path / "excel.csv"
    t.write_bytes(b"\xef\xbb\xbfaspect_deg,rcs_dbsm\r\n0,10\r\n90,20\r\n")
    aspect, value = rcs.load_table(str(t))
    assert aspect.tolist() == [0.0, math.pi / 2] and value.tolist() == [10.0, 20.0]


@pytest.mark.parametrize("sep", [";", "\t"])
def test_a_table_with_another_separator_says_so(tmp_path, sep):
    t = tmp_path / "semi.csv"
    t.write_text(f"aspect_deg{sep}rcs_dbsm\n0{sep}10\n90{sep}20\n")
    with pytest.raises(InputFileError, match=r"line 1: .*separated by .*; the table is "
                                             r"comma-separated"):
        rcs.load_table(str(t))
