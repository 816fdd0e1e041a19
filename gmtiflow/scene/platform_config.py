"""The ``platform`` config group: one typed schema for every kind of platform (docs/platform.md).

``kind`` chooses the model; the keys of the other kinds are ignored but still range-checked
(so a preset that sets them wrongly fails at once, not when someone switches kind).

* ``fixed_wing`` — a waypoint loop flown with coordinated turns (:mod:`gmtiflow.scene.fixed_wing`).
* ``rotorcraft`` — straight legs between waypoints, hovering ``hover_s`` at each one
  (:mod:`gmtiflow.scene.rotorcraft`).
* ``trajectory`` — an external log read from ``path`` (:mod:`gmtiflow.scene.trajectory`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum
from typing import Any, List, Optional

import numpy as np

from gmtiflow.scene import flight
from gmtiflow.schema import (MAX_MAGNITUDE, Problem, in_range, is_number, point_problems,
                             positive)


class PlatformKind(str, Enum):
    """Which platform model flies the scene."""

    fixed_wing = "fixed_wing"
    rotorcraft = "rotorcraft"
    trajectory = "trajectory"


@dataclass
class PlatformConfig:
    """Platform.  ``waypoints_m``: list of ``[x_m, y_m, altitude_m]`` in scene ENU."""

    kind: PlatformKind = PlatformKind.fixed_wing
    waypoints_m: List[Any] = field(default_factory=lambda: [
        [12426.4, -30000.0, 6000.0], [-12426.4, -30000.0, 6000.0],
        [-30000.0, -12426.4, 6000.0], [-30000.0, 12426.4, 6000.0],
        [-12426.4, 30000.0, 6000.0], [12426.4, 30000.0, 6000.0],
        [30000.0, 12426.4, 6000.0], [30000.0, -12426.4, 6000.0]])
    """The default orbit: a clockwise 30 km circle around the scene (conf/platform/default.yaml)."""
    speed_mps: float = 150.0
    """Horizontal speed (fixed_wing: constant; rotorcraft: cruise speed on the legs)."""
    turn_lead_s: float = 82.84
    """fixed_wing: ``t`` of paper eq. 5: the turn starts ``speed_mps * turn_lead_s`` before a corner."""
    max_bank_deg: float = 60.0
    """fixed_wing: a corner whose coordinated turn banks more than this is a config error."""
    hover_s: Any = 0.0
    """rotorcraft: hold time at each waypoint, one number or one per waypoint (≥ 0)."""
    accel_mps2: float = 2.0
    """rotorcraft: horizontal acceleration leaving and braking into each waypoint."""
    path: Optional[str] = None
    """trajectory: CSV file (docs/platform.md), absolute or relative to the current directory."""
    time_offset_s: float = 0.0
    """trajectory: scene time ``t`` reads the log at ``t + time_offset_s``."""

    def problems(self) -> List[Problem]:
        out = positive(self, "speed_mps", "turn_lead_s", "accel_mps2")
        out += in_range(self, "max_bank_deg", 0.0, 90.0, lo_open=True)
        if not is_number(self.time_offset_s):
            out.append(Problem("time_offset_s", f"must be a finite number of seconds, got "
                                                f"{self.time_offset_s!r}"))
        out += self._hover_problems()
        kind = PlatformKind(self.kind)
        if kind is PlatformKind.trajectory and not self.path:
            out.append(Problem("path", "kind=trajectory needs the CSV file of the trajectory"))
        wps = self.waypoints_m
        if len(wps) < 2:
            return out + [Problem("waypoints_m", f"needs at least 2 waypoints, got {len(wps)}")]
        for i, wp in enumerate(wps):
            out += point_problems(f"waypoints_m[{i}]", wp, dims=(3,),
                                  what="[x_m, y_m, altitude_m]")
        if out:
            return out
        xy = np.asarray(wps, float)[:, :2]
        if np.abs(xy).max() > MAX_MAGNITUDE:    # config.magnitude_problems names it; legs and
            return out                          # turns of such a path overflow, or mislead
        legs = np.linalg.norm(np.roll(xy, -1, axis=0) - xy, axis=1)
        for i, length in enumerate(legs):
            if length == 0.0:
                j = (i + 1) % len(wps)
                out.append(Problem("waypoints_m",
                                   f"waypoints {i} and {j} coincide in x, y (zero-length leg)"))
        if out or kind is not PlatformKind.fixed_wing:
            return out
        lead_m = self.speed_mps * self.turn_lead_s
        shortest = float(legs.min())
        if 2.0 * lead_m > shortest:
            out.append(Problem("turn_lead_s",
                               f"turns start speed_mps*turn_lead_s = {lead_m:g} m before each corner,"
                               f" which must be at most half the shortest leg ({shortest:g} m / 2 = "
                               f"{shortest / 2:g} m)"))
        return out + self._bank_problems(xy)

    def _hover_problems(self) -> List[Problem]:
        hover = self.hover_s
        if isinstance(hover, (list, tuple)):
            if len(hover) != len(self.waypoints_m):
                return [Problem("hover_s", f"needs one hold time per waypoint "
                                           f"({len(self.waypoints_m)}), got {len(hover)}")]
            items = [(f"hover_s[{i}]", h) for i, h in enumerate(hover)]
        else:
            items = [("hover_s", hover)]
        return [Problem(key, f"must be a finite number of seconds >= 0, got {h!r}")
                for key, h in items if not (is_number(h) and h >= 0)]

    def _bank_problems(self, xy: np.ndarray) -> List[Problem]:
        """A corner whose coordinated turn (paper eq. 5) banks beyond ``max_bank_deg``."""
        alpha = flight.corner_turns_rad(xy)
        bank = flight.bank_angle_rad(self.speed_mps, alpha, self.turn_lead_s)
        limit = math.radians(self.max_bank_deg)
        return [Problem(f"waypoints_m[{i}]",
                        f"the coordinated turn at this waypoint (heading change "
                        f"{math.degrees(abs(alpha[i])):.1f}°) banks {math.degrees(bank[i]):.1f}° "
                        f"= arctan(v tan(α/2) / (t g)) (paper eq. 5), more than max_bank_deg = "
                        f"{self.max_bank_deg:g}°; raise turn_lead_s, lower speed_mps or raise "
                        f"max_bank_deg")
                for i in np.flatnonzero(bank > limit)]

    def hover_times_s(self) -> np.ndarray:
        """Hold time at each waypoint (rotorcraft), one per waypoint."""
        n = len(self.waypoints_m)
        if isinstance(self.hover_s, (list, tuple)):
            return np.asarray(self.hover_s, float)
        return np.full(n, float(self.hover_s))
