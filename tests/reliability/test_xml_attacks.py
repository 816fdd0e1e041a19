"""Every XML entry point against XXE (local file and network), parameter entities, XInclude,
external DTDs and entity-expansion bombs (docs/reliability.md, "XML").

Entry points: the OSM loader (``roadmap=osm`` in a run), ``formats.read_xml``,
``formats.xmldoc.validate_xml`` and ``gmtiflow-convert`` on a ``.xml`` file.  A listening socket
on localhost records any connection: the parsers must never touch the network.  The secret's
text must appear in no table and no message.  (tests/scene/test_osm.py and
tests/formats/test_xmldoc.py hold the first XXE / billion-laughs cases for each reader.)
"""
from __future__ import annotations

import socket
import threading
import time

import pytest

from gmtiflow.formats import xmldoc
from gmtiflow.formats.errors import FormatError
from gmtiflow import convert, pipeline
from gmtiflow.compose import compose
from gmtiflow.errors import GmtiflowError, RoadMapError
from gmtiflow.scene.osm import load_osm

SECRET = "TOP-SECRET-7f3a"

OSM_BODY = ('<node id="1" lat="43.73" lon="7.42"/><node id="2" lat="43.731" lon="7.421"/>'
            '<way id="7"><nd ref="1"/><nd ref="2"/><tag k="highway" v="primary"/>'
            '<tag k="name" v="{ref}"/></way>')
GMTI_BODY = ('<PacketHeader nationality="{ref}"/>')


@pytest.fixture
def listener():
    """A TCP server on localhost that counts connections (none may arrive)."""
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(8)
    srv.settimeout(0.2)
    hits = []
    stop = threading.Event()

    def serve():
        while not stop.is_set():
            try:
                conn, _ = srv.accept()
            except OSError:
                continue
            hits.append(conn.recv(200))
            conn.close()

    t = threading.Thread(target=serve, daemon=True)
    t.start()
    yield f"http://127.0.0.1:{srv.getsockname()[1]}", hits
    stop.set()
    t.join(2)
    srv.close()


def attacks(secret_uri: str, url: str, root: str, body: str) -> dict:
    """Hostile documents for a root element ``root``; ``body`` holds ``{ref}`` for the payload."""
    laughs = ('<!ENTITY a "aaaaaaaaaa">' + "".join(
        f'<!ENTITY {c} "{("&" + p + ";") * 10}">' for p, c in zip("abcdefgh", "bcdefghi")))
    return {
        "xxe_file": (f'<!DOCTYPE {root} [<!ENTITY x SYSTEM "{secret_uri}">]>', "&x;"),
        "xxe_network": (f'<!DOCTYPE {root} [<!ENTITY x SYSTEM "{url}/entity">]>', "&x;"),
        "parameter_entity": (f'<!DOCTYPE {root} [<!ENTITY % p SYSTEM "{url}/param.dtd"> %p;]>',
                             "x"),
        "external_dtd": (f'<!DOCTYPE {root} SYSTEM "{url}/external.dtd">', "x"),
        "billion_laughs": (f"<!DOCTYPE {root} [{laughs}]>", "&i;"),
        "quadratic": (f'<!DOCTYPE {root} [<!ENTITY q "{"q" * 50_000}">]>', "&q;" * 2000),
        "xinclude": ("", "x"),
    }


def document(root: str, ns: str, doctype: str, body: str, ref: str, kind: str,
             url: str) -> bytes:
    inner = body.format(ref=ref) if "&" not in ref or kind != "xinclude" else body
    if kind == "xinclude":
        inner += (f'<xi:include xmlns:xi="http://www.w3.org/2001/XInclude" href="{url}/inc.xml" '
                  f'parse="text"/>')
    return (f'<?xml version="1.0"?>\n{doctype}\n<{root}{ns}>{inner}</{root}>').encode()


def _xml_entry_points(tmp_path):
    def read(data):
        xmldoc.read_xml(data)

    def validate(data):
        xmldoc.validate_xml(data)

    def convert_cli(data):
        src = tmp_path / "in.xml"
        src.write_bytes(data)
        code = convert.main([str(src), "--to", "csv", "-o", str(tmp_path / "out.csv")])
        if code != 0:
            raise FormatError("gmtiflow-convert refused it")   # its message: checked below
        return code
    return {"read_xml": read, "validate_xml": validate, "gmtiflow-convert": convert_cli}


def test_osm_loader_and_run_refuse_or_ignore_every_attack(tmp_path, listener):
    url, hits = listener
    secret = tmp_path / "secret.txt"
    secret.write_text(SECRET)
    for kind, (doctype, ref) in attacks(secret.as_uri(), url, "osm", OSM_BODY).items():
        path = tmp_path / f"{kind}.osm"
        path.write_bytes(document("osm", ' version="0.6"', doctype, OSM_BODY, ref, kind, url))
        t0 = time.process_time()
        try:
            roadmap = load_osm(path)
        except RoadMapError as exc:
            assert SECRET not in str(exc), kind
        else:                          # parsed with the entity left unresolved: no secret
            assert SECRET not in repr(roadmap.edges) + repr(roadmap.nodes), kind
        assert time.process_time() - t0 < 5.0, kind
    # the whole run, as `gmtiflow roadmap=osm roadmap.path=...` would do it
    out = tmp_path / "run"
    cfg = compose(["roadmap=osm", f"roadmap.path={tmp_path / 'xxe_file.osm'}",
                   "scene.duration_s=5", "export=all", "report=none", "progress=false",
                   "cache.enabled=false", "vehicles=random", "vehicles.random.count=1"])
    try:
        pipeline.run(cfg, out)
    except GmtiflowError as exc:
        assert SECRET not in str(exc)
    for f in out.glob("*"):
        assert SECRET.encode() not in f.read_bytes(), f.name
    assert hits == [], hits


def test_gmti_xml_readers_and_converter_refuse_every_attack(tmp_path, listener, capsys):
    url, hits = listener
    secret = tmp_path / "secret.txt"
    secret.write_text(SECRET)
    ns = f' xmlns="{xmldoc.NAMESPACE}"'
    tried = 0
    for kind, (doctype, ref) in attacks(secret.as_uri(), url, "GmtiDocument",
                                        GMTI_BODY).items():
        data = document("GmtiDocument", ns, doctype, GMTI_BODY, ref, kind, url)
        for name, call in _xml_entry_points(tmp_path).items():
            t0 = time.process_time()
            with pytest.raises(FormatError) as exc:
                call(data)
            tried += 1
            err = capsys.readouterr().err
            assert SECRET not in str(exc.value) + err, (kind, name)
            assert "Traceback" not in err
            assert time.process_time() - t0 < 5.0, (kind, name)
            assert not (tmp_path / "out.csv").exists()
    assert tried == 21
    assert hits == [], hits
