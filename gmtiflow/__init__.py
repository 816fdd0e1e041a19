"""gmtiflow: simulate what an airborne GMTI radar reports about vehicles on a road network."""
from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("gmtiflow")
except PackageNotFoundError:  # running from a checkout that is not installed
    __version__ = "0.0.0+unknown"

__all__ = ["__version__", "stream"]


def __getattr__(name):
    # ``gmtiflow.stream(run_file)``: the tracker protocol's batches of a run, imported on first
    # use so that ``import gmtiflow`` stays cheap.
    if name == "stream":
        from gmtiflow.evaluate.protocol import stream
        return stream
    raise AttributeError(f"module 'gmtiflow' has no attribute {name!r}")
