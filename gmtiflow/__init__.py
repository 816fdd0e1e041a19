"""gmtiflow: simulate what an airborne GMTI radar reports about vehicles on a road network."""
from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("gmtiflow")
except PackageNotFoundError:  # running from a checkout that is not installed
    __version__ = "0.0.0+unknown"

__all__ = ["__version__"]
