"""gmtiflow: simulate what an airborne GMTI radar reports about vehicles on a road network."""

__all__ = ["__version__", "stream"]


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version   # ~0.05 s: on first use
    try:
        return version("gmtiflow")
    except PackageNotFoundError:  # running from a checkout that is not installed
        return "0.0.0+unknown"


def __getattr__(name):
    # ``gmtiflow.__version__`` is read from the installed metadata on first use and
    # ``gmtiflow.stream(run_file)`` (the tracker protocol's batches of a run) imported on first
    # use, so that ``import gmtiflow`` (and with it ``gmtiflow --help``) stays cheap.
    if name == "__version__":
        globals()["__version__"] = value = _version()
        return value
    if name == "stream":
        from gmtiflow.evaluate.protocol import stream
        return stream
    raise AttributeError(f"module 'gmtiflow' has no attribute {name!r}")
