"""formats is a leaf package: importing all of it pulls in neither gmtiflow nor optional extras."""
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_formats_never_imports_gmtiflow():
    code = ("import sys, formats, formats.stanag4607, formats.xmldoc, formats.csvtable, "
            "formats.geojson, formats.synthetic; "
            "bad = sorted(m for m in sys.modules if m.split('.')[0] in "
            "('gmtiflow', 'pandas', 'stonesoup', 'pymap3d', 'scipy', 'h5py')); print(bad)")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "[]"


def test_public_api_and_xsd_ship_with_the_package():
    import formats
    from formats import xmldoc
    assert xmldoc.XSD_PATH.parent == Path(formats.__file__).parent and xmldoc.XSD_PATH.exists()
    for name in formats.__all__:
        assert hasattr(formats, name), name
    assert issubclass(formats.FormatError, ValueError)
