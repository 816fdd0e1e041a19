"""GMTI XML: XSD validity, exact round trips, hardened parsing."""
from __future__ import annotations

import time

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st
from lxml import etree

from gmtiflow.formats import synthetic, xmldoc
from gmtiflow.formats.errors import FormatError

META = {"epoch_utc": synthetic.EPOCH_UTC}


def _assert_tables_equal(expected, got, columns):
    for col in expected:
        if col not in columns:
            continue
        a, b = np.asarray(expected[col]), got[col]
        if a.dtype.kind == "f":
            np.testing.assert_array_equal(a, b, err_msg=col)      # bit-exact, NaN == NaN
        else:
            assert a.tolist() == b.tolist(), col


def test_written_document_validates_against_the_xsd(tmp_path):
    dwells, dets = synthetic.tables(10, 80)
    path = tmp_path / "run.xml"
    xmldoc.write_xml(path, dwells, dets, dict(META, pd=0.9, false_alarm_density_per_m2=1e-6))
    schema = etree.XMLSchema(etree.parse(str(xmldoc.XSD_PATH)))
    assert schema.validate(etree.parse(str(path))), schema.error_log
    xmldoc.validate_xml(path)


def test_round_trip_is_exact_and_rewrite_is_byte_identical():
    dwells, dets = synthetic.tables(12, 100, seed=4)
    dets["snr_db"][3] = np.nan                     # unknown values survive as NaN
    dets["range_rate_mps"][4] = np.inf
    data = xmldoc.encode_xml(dwells, dets, META)
    r = xmldoc.read_xml(data)
    _assert_tables_equal(dwells, r["dwells"], xmldoc.DWELL_COLUMNS)
    _assert_tables_equal(dets, r["detections"], xmldoc.DETECTION_COLUMNS)
    assert r["detections"]["dwell_id"].tolist() == dets["dwell_id"].tolist()
    assert xmldoc.encode_xml(r["dwells"], r["detections"], r["meta"]) == data


def test_structure_mirrors_4607():
    dwells, dets = synthetic.tables(4, 10)
    root = etree.fromstring(xmldoc.encode_xml(dwells, dets, META))
    ns = {"g": xmldoc.NAMESPACE}
    assert [etree.QName(e).localname for e in root][:3] == ["PacketHeader", "Mission", "JobDefinition"]
    assert len(root.findall("g:Dwell", ns)) == 4
    assert len(root.findall("g:Dwell/g:TargetReport", ns)) == 10
    assert root.find("g:Mission", ns).get("referenceDate") == "2026-11-21"
    assert root.find("g:Dwell", ns).get("timeUtc") == "2026-11-21T13:00:00.263000Z"
    assert len(root.findall("g:JobDefinition/g:BoundingArea/g:Point", ns)) == 4


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**31), n_dwells=st.integers(1, 10), n_dets=st.integers(0, 40),
       lat=st.floats(-80.0, 80.0), lon=st.floats(-170.0, 170.0))
def test_round_trip_random_tables(seed, n_dwells, n_dets, lat, lon):
    dwells, dets = synthetic.tables(n_dwells, n_dets, seed=seed, lat0=lat, lon0=lon)
    r = xmldoc.read_xml(xmldoc.encode_xml(dwells, dets, META))
    _assert_tables_equal(dwells, r["dwells"], xmldoc.DWELL_COLUMNS)
    if n_dets:
        _assert_tables_equal(dets, r["detections"], xmldoc.DETECTION_COLUMNS)


def test_writer_refuses_values_the_xsd_would_reject():
    dwells, dets = synthetic.tables(2, 3)
    dets["lat_deg"][1] = 91.0
    with pytest.raises(ValueError, match="lat_deg"):
        xmldoc.encode_xml(dwells, dets, META)


XXE = b"""<?xml version="1.0"?>
<!DOCTYPE GmtiDocument [<!ENTITY xxe SYSTEM "file:///etc/passwd">]>
<GmtiDocument xmlns="urn:gmtiflow:gmti:1" formatVersion="1" edition="30"
  sceneEpochUtc="2026-01-01T00:00:00Z"><PacketHeader nationality="&xxe;"/></GmtiDocument>"""

LAUGHS = b"""<?xml version="1.0"?>
<!DOCTYPE lolz [
 <!ENTITY lol "lol">
 <!ENTITY lol1 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">
 <!ENTITY lol2 "&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;">
 <!ENTITY lol3 "&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;">
 <!ENTITY lol4 "&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;">
 <!ENTITY lol5 "&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;">
 <!ENTITY lol6 "&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;">
 <!ENTITY lol7 "&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;">
 <!ENTITY lol8 "&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;">
 <!ENTITY lol9 "&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;">
]>
<GmtiDocument xmlns="urn:gmtiflow:gmti:1">&lol9;</GmtiDocument>"""


def test_xxe_is_refused_without_reading_the_file(tmp_path):
    secret = tmp_path / "secret.txt"
    secret.write_text("TOP-SECRET-CONTENT")
    doc = XXE.replace(b"file:///etc/passwd", secret.as_uri().encode())
    with pytest.raises(FormatError, match="(?i)entity|DOCTYPE") as exc:
        xmldoc.read_xml(doc)
    assert "TOP-SECRET" not in str(exc.value)
    # an entity in element content parses (unresolved) and is refused for its DOCTYPE
    doc = doc.replace(b'<PacketHeader nationality="&xxe;"/>', b"&xxe;")
    with pytest.raises(FormatError, match="DOCTYPE") as exc:
        xmldoc.read_xml(doc)
    assert "TOP-SECRET" not in str(exc.value)


def test_billion_laughs_is_refused_quickly():
    t0 = time.process_time()
    with pytest.raises(FormatError):
        xmldoc.read_xml(LAUGHS)
    assert time.process_time() - t0 < 5.0       # a guard against expansion, not a speed test


def test_malformed_and_invalid_documents_name_line_and_column(tmp_path):
    with pytest.raises(FormatError, match=r"line \d+, column \d+: not well-formed"):
        xmldoc.read_xml(b"<GmtiDocument><unclosed></GmtiDocument>")
    dwells, dets = synthetic.tables(2, 3)
    data = xmldoc.encode_xml(dwells, dets, META).replace(b'lat_deg="', b'lat_deg="x', 1)
    with pytest.raises(FormatError, match=r"line \d+, column \d+: not valid against gmti.xsd"):
        xmldoc.read_xml(data)
    data = xmldoc.encode_xml(dwells, dets, META).replace(b"<Mission ", b"<Mision ", 1)
    with pytest.raises(FormatError, match="not valid"):
        xmldoc.read_xml(data)
    with pytest.raises(FormatError, match="cannot read"):
        xmldoc.read_xml(tmp_path / "missing.xml")
    with pytest.raises(FormatError):
        xmldoc.read_xml(b"\xff\xfe\x00garbage")


def test_empty_run():
    area = [(43.8, 7.3), (43.8, 7.5), (43.7, 7.5), (43.7, 7.3)]
    r = xmldoc.read_xml(xmldoc.encode_xml({}, {}, dict(META, bounding_area=area)))
    assert r["dwells"] == {} and len(r["detections"]["det_id"]) == 0
    assert r["meta"]["bounding_area"] == area


AREA = [(43.8, 7.3), (43.8, 7.5), (43.7, 7.5), (43.7, 7.3)]


def _assert_same_table(written, got, columns, what):
    """Every carried column of ``written`` comes back with its dtype and values (NaN as NaN)."""
    carried = [c for c in written if c in columns]
    assert set(carried) <= set(got), (what, sorted(set(carried) - set(got)))
    for c in carried:
        a, b = np.asarray(written[c]), got[c]
        assert b.dtype == a.dtype and b.shape == a.shape, (what, c, a.dtype, b.dtype, b.shape)
        np.testing.assert_array_equal(b, a, err_msg=f"{what}.{c}")


def _xmllint_valid(path):
    import shutil
    import subprocess
    if shutil.which("xmllint") is None:
        return True
    out = subprocess.run(["xmllint", "--noout", "--schema", str(xmldoc.XSD_PATH), str(path)],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    return True


def _written_and_read(path, dwells, dets):
    """Write ``dwells``/``dets`` to ``path`` (xmllint-valid), read them back, and check every
    carried column of both tables; returns what was read."""
    xmldoc.write_xml(path, dwells, dets, dict(META, bounding_area=AREA))
    assert _xmllint_valid(path)
    r = xmldoc.read_xml(path)
    _assert_same_table(dwells, r["dwells"], xmldoc.DWELL_COLUMNS, "dwells")
    _assert_same_table(dets, r["detections"], xmldoc.DETECTION_COLUMNS, "detections")
    return r


def test_round_trip_keeps_all_nan_columns(tmp_path):
    """A column with no known value (``wrap_velocity_mps`` of a run without PRF, the SNR and RCS
    of reports nobody measured) is written as absent attributes; it comes back as NaN, not
    dropped."""
    dwells, dets = synthetic.tables(5, 30, seed=2)
    dwells["wrap_velocity_mps"][:] = np.nan
    for c in ("wrap_velocity_mps", "snr_db", "rcs_dbsm", "lat_deg", "lon_deg", "height_m"):
        dets[c][:] = np.nan
    path = tmp_path / "nan.xml"
    r = _written_and_read(path, dwells, dets)
    assert xmldoc.encode_xml(r["dwells"], r["detections"], r["meta"]) == path.read_bytes()


def test_round_trip_keeps_empty_tables_and_their_columns(tmp_path):
    """No dwells and no reports (a run shorter than one scan): both tables come back with every
    column written, zero rows and the dtypes written."""
    dwells, dets = synthetic.tables(3, 4)
    for table in (dwells, dets):
        for c in table:
            table[c] = table[c][:0]
    r = _written_and_read(tmp_path / "empty.xml", dwells, dets)
    assert r["detections"]["dwell_id"].dtype == np.int64
    # dwells without reports: the reports' columns are still known
    dwells, dets = synthetic.tables(3, 4)
    dets = {c: v[:0] for c, v in dets.items()}
    r = xmldoc.read_xml(xmldoc.encode_xml(dwells, dets, META))
    _assert_same_table(dets, r["detections"], xmldoc.DETECTION_COLUMNS, "detections")


def test_documents_without_a_column_list_still_read():
    """Documents written before the column list (formatVersion 1 without <Columns>) validate and
    read as before: a column is there when some element has its attribute."""
    dwells, dets = synthetic.tables(3, 6)
    dets["snr_db"][:] = np.nan
    data = xmldoc.encode_xml(dwells, dets, META)
    root = etree.fromstring(data)
    for el in root.findall(f"{{{xmldoc.NAMESPACE}}}Columns"):
        root.remove(el)
    old = etree.tostring(root, xml_declaration=True, encoding="UTF-8")
    r = xmldoc.read_xml(old)
    assert "snr_db" not in r["detections"]
    _assert_tables_equal(dets, r["detections"], set(xmldoc.DETECTION_COLUMNS) - {"snr_db"})
    _assert_tables_equal(dwells, r["dwells"], xmldoc.DWELL_COLUMNS)


def test_a_column_list_naming_an_unknown_column_is_invalid():
    dwells, dets = synthetic.tables(2, 2)
    data = xmldoc.encode_xml(dwells, dets, META)
    assert b'<Columns dwell="dwell_id ' in data
    with pytest.raises(FormatError, match="not valid against gmti.xsd"):
        xmldoc.read_xml(data.replace(b'<Columns dwell="dwell_id ', b'<Columns dwell="colour ', 1))


def test_the_xsd_column_names_are_the_writers():
    xsd = etree.parse(str(xmldoc.XSD_PATH))
    ns = {"xs": "http://www.w3.org/2001/XMLSchema"}
    for name, columns in (("DwellColumn", xmldoc.DWELL_COLUMNS),
                          ("TargetReportColumn", xmldoc.DETECTION_COLUMNS)):
        values = xsd.xpath(f"//xs:simpleType[@name='{name}']//xs:enumeration/@value",
                           namespaces=ns)
        assert values == list(columns), name
