"""formats is a leaf package: importing all of it pulls in no other part of gmtiflow nor optional extras.

It lives in ``formats/`` at the repository's top level and installs as ``gmtiflow.formats`` (a
top-level ``formats`` in site-packages could collide with any other project's)."""
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_formats_never_imports_gmtiflow():
    code = ("import sys, gmtiflow.formats, gmtiflow.formats.stanag4607, gmtiflow.formats.xmldoc, "
            "gmtiflow.formats.csvtable, gmtiflow.formats.geojson, gmtiflow.formats.synthetic; "
            "bad = sorted(m for m in sys.modules if (m.startswith('gmtiflow.') and not "
            "m.startswith('gmtiflow.formats')) or m.split('.')[0] in "
            "('pandas', 'stonesoup', 'pymap3d', 'scipy', 'h5py', 'formats')); print(bad)")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "[]"


def test_public_api_and_xsd_ship_with_the_package():
    from gmtiflow import formats
    from gmtiflow.formats import xmldoc
    assert xmldoc.XSD_PATH.parent == Path(formats.__file__).parent and xmldoc.XSD_PATH.exists()
    for name in formats.__all__:
        assert hasattr(formats, name), name
    assert issubclass(formats.FormatError, ValueError)


def test_formats_sources_import_nothing_outside_the_package():
    for path in (ROOT / "formats").glob("*.py"):
        text = path.read_text()
        assert "from .." not in text and "import gmtiflow" not in text, path
        assert "from gmtiflow" not in text, path


def test_lazy_names_and_submodules_resolve_in_a_fresh_interpreter():
    """The writers and submodules load on first use (start-up): attribute access still works."""
    code = ("import sys; from gmtiflow import formats; assert 'lxml' not in sys.modules; "
            "assert formats.xmldoc.DETECTION_COLUMNS and formats.stanag4607.READ_TABLES; "
            "from gmtiflow.formats import write_4607, read_xml; print(write_4607.__module__)")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "gmtiflow.formats.stanag4607" or \
        out.stdout.strip().startswith("gmtiflow.formats.s4607")
