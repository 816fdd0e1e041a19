"""The airborne platform: its state at any instants, for each kind of platform (paper §4).

The interface the rest of the pipeline uses is one plain function of a config:
:func:`platform_states` ``(cfg, origin, time_s) -> /platform table``, or, to evaluate the same
platform at many sets of instants, :class:`Platform` ``(cfg, origin).state_at(time_s)``.
Each kind lives in its own module (docs/platform.md):

* ``fixed_wing`` — :mod:`gmtiflow.scene.fixed_wing`, waypoint loop with coordinated turns;
* ``rotorcraft`` — :mod:`gmtiflow.scene.rotorcraft`, legs between waypoints and hovers at them;
* ``trajectory`` — :mod:`gmtiflow.scene.trajectory`, an external log (CSV) interpolated.

The schema is :class:`~gmtiflow.scene.platform_config.PlatformConfig` (re-exported here).
"""
from __future__ import annotations

from gmtiflow import frames
from gmtiflow.errors import ConfigError
from gmtiflow.scene.fixed_wing import FixedWing, Orbit, build_orbit
from gmtiflow.scene.flight import G_MPS2, bank_angle_rad
from gmtiflow.scene.platform_config import PlatformConfig, PlatformKind
from gmtiflow.scene.rotorcraft import Rotorcraft
from gmtiflow.scene.trajectory import Trajectory
from gmtiflow.tables import Table

__all__ = ["G_MPS2", "Orbit", "Platform", "PlatformConfig", "PlatformKind", "bank_angle_rad",
           "build_orbit", "platform_states"]

_KINDS = {PlatformKind.fixed_wing: FixedWing, PlatformKind.rotorcraft: Rotorcraft,
          PlatformKind.trajectory: Trajectory}


class Platform:
    """One platform of any kind, validated and laid out once; :meth:`state_at` is vectorised."""

    def __init__(self, cfg: PlatformConfig, origin: frames.Origin):
        problems = cfg.problems()
        if problems:
            raise ConfigError("invalid config: " + "; ".join(
                f"platform.{p.key}: {p.message}" for p in problems))
        self.cfg = cfg
        self.origin = origin
        self.kind = PlatformKind(cfg.kind)
        self.model = _KINDS[self.kind](cfg, origin)

    @property
    def orbit(self) -> Orbit:
        """The laid-out orbit of a fixed-wing platform."""
        return self.model.orbit

    def state_at(self, time_s) -> Table:
        """The /platform columns (docs/tables.md) at each of ``time_s`` (scene seconds)."""
        return self.model.state_at(time_s)


def platform_states(cfg: PlatformConfig, origin: frames.Origin, time_s) -> Table:
    """The /platform table of the platform ``cfg`` describes at ``time_s`` (scene seconds)."""
    return Platform(cfg, origin).state_at(time_s)
