"""The candidate cause's interface (:class:`Cause`: fitted numbers theta, their transformed
space u and the plant overrides they make) and the drives' joint groups that several causes
share one value per (``JOINT_GROUPS``)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from impactqp.controller.model.tool_description import ToolDescription
from impactqp.sim.plant import PlantParameters


def payload_com(tool: ToolDescription) -> tuple[float, float, float]:
    """The default payload centre of mass: the centre of the tool's contact geometry, relative to
    the contact point (the payload body's origin, ``sim.scene``)."""
    return tuple(float(x) for x in tool.geometry.centre - tool.contact_point)


# Joint groups of the Panda's drives: large motors on joints 1-4, small ones on joints 5-7.
JOINT_GROUPS = ((0, 1, 2, 3), (4, 5, 6))
GROUPED_JOINTS = sum(len(group) for group in JOINT_GROUPS)
"""The joints the groups cover: every joint of the arm."""
GRID_POINTS = {1: 7, 2: 5}


def per_group(values: tuple[float, ...]) -> list[float]:
    """The joint values (one per joint of ``JOINT_GROUPS``) of one value per joint group."""
    out = [0.0] * GROUPED_JOINTS
    for group, value in zip(JOINT_GROUPS, values):
        for j in group:
            out[j] = float(value)
    return out


def group_means(values) -> np.ndarray:
    values = np.asarray(values, dtype=float)
    return np.array([values[list(group)].mean() for group in JOINT_GROUPS])


class Cause:
    """A candidate cause: ``plant(nominal, u)`` builds the plant for the fitted vector u."""

    name: str = ""
    labels: tuple[str, ...] = ()
    log_scale: tuple[bool, ...] = ()
    lower: tuple[float, ...] = ()
    upper: tuple[float, ...] = ()

    # A realistic range of theta and the tangential speeds (m/s; ``dataset generate`` runs them
    # at its tangential series' normal speed) a dataset needs for the cause to show, for tests
    # and benchmarks that hide it in simulated data.
    realistic: tuple[tuple[float, ...], tuple[float, ...]] = ((), ())
    tangential_speeds_needed: tuple[float, ...] = ()

    def nominal_theta(self, nominal: PlantParameters) -> np.ndarray:
        raise NotImplementedError

    def grid(self, nominal: PlantParameters) -> list[np.ndarray]:
        """Start points of the fit (in u): the nominal value and a regular grid over the bounds
        (``GRID_POINTS`` per axis); a cause with more parameters gives its own."""
        lo, hi = self.u_bounds()
        axes = [np.linspace(a, b, GRID_POINTS[len(lo)]) for a, b in zip(lo, hi)]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, len(lo))
        return [self.to_u(self.nominal_theta(nominal))] + [np.array(p) for p in grid]

    def refined(self) -> "Cause | None":
        """The same effect with more parameters (per joint), which the search tries in place of
        this cause once it is chosen, and keeps when the data support it; None: no refinement."""
        return None

    def settling_trials(self, index: int, side: str, known: float, normal_speeds: np.ndarray) -> str:
        """Plain words for the trials that would bound parameter ``index`` on ``side`` ("below"
        or "above") when the data leave it open there; ``known`` is the closed end of its
        interval (the fitted value when both ends are open), ``normal_speeds`` the reference
        normal speeds (m/s) of the dataset's trials."""
        return "more trials: other postures and a wider range of normal speeds"

    def overrides(self, theta: np.ndarray) -> dict:
        raise NotImplementedError

    def theta_of(self, overrides: dict) -> np.ndarray:
        """The fitted numbers theta read back from plant overrides (inverse of ``overrides``)."""
        raise NotImplementedError

    # transformed space -------------------------------------------------------------
    def to_u(self, theta: np.ndarray) -> np.ndarray:
        theta = np.clip(np.asarray(theta, float), self.lower, self.upper)
        return np.where(self.log_scale, np.log(np.maximum(theta, 1e-12)), theta)

    def to_theta(self, u: np.ndarray) -> np.ndarray:
        return np.where(self.log_scale, np.exp(u), u)

    def u_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self.to_u(self.lower), self.to_u(self.upper)

    def plant(self, nominal: PlantParameters, u: np.ndarray) -> PlantParameters:
        return replace(nominal, **self.overrides(self.to_theta(u)))
