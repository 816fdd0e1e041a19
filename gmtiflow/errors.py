"""Error types of gmtiflow.

Every error a user can cause (bad config value, bad road map, bad file) is raised as one of
these, with a message that names *what* (key, file, column) and *where* (line, offset) and
what was expected.  The CLI turns them into one line on stderr and a non-zero exit; anything
else escaping is a bug.
"""
from __future__ import annotations


class GmtiflowError(Exception):
    """Base class of all errors gmtiflow reports to the user."""


class ConfigError(GmtiflowError, ValueError):
    """A configuration value is out of range or inconsistent (names the full key path)."""


class InputFileError(GmtiflowError):
    """An input file (road map, OSM, DEM, RCS table, HDF5 ...) is missing or malformed."""


class RoadMapError(InputFileError):
    """A road map is empty, malformed, or a route cannot be found on it."""


class StoreError(InputFileError):
    """An HDF5 run file is missing, truncated, incomplete or of another layout version."""


class CompositionError(ConfigError):
    """Hydra could not compose the config from the overrides: an unknown group option or key,
    a value of the wrong type, an override it cannot parse (:mod:`gmtiflow.compose_errors`).
    The message is one line; ``hint`` at most one more (None without)."""

    def __init__(self, message: str, hint=None):
        super().__init__(message)
        self.hint = hint
