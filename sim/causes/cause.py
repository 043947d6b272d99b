"""The candidate cause's interface (:class:`Cause`: fitted numbers theta, their transformed
space u and the plant overrides they make) and the drives' joint groups that several causes
share one value per (``joint_groups``), read from the number of joints: no arm is a constant."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from impactqp.controller.model.tool_description import ToolDescription
from impactqp.sim.plant import PlantParameters


def payload_com(tool: ToolDescription) -> tuple[float, float, float]:
    """The default payload centre of mass: the centre of the tool's contact geometry, relative to
    the contact point (the payload body's origin, ``sim.scene``)."""
    return tuple(float(x) for x in tool.geometry.centre - tool.contact_point)


GRID_POINTS = {1: 7, 2: 5}


def joint_groups(joints: int) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """The drive groups of an arm of ``joints`` joints (0-based indices): the larger drives of
    the first ceil(n / 2) joints (shoulder and elbow) and the smaller ones of the others (the
    wrist): the Panda's and the FR3's joints 1-4 and 5-7, the UR5's 1-3 and 4-6."""
    split = (joints + 1) // 2
    return tuple(range(split)), tuple(range(split, joints))


def group_name(group: tuple[int, ...]) -> str:
    """``joints 1-4`` for the 0-based joint indices (0, 1, 2, 3)."""
    return f"joints {group[0] + 1}-{group[-1] + 1}" if len(group) > 1 else f"joint {group[0] + 1}"


def per_group(values, joints: int) -> list[float]:
    """The ``joints`` joint values of one value per joint group (``joint_groups``)."""
    out = [0.0] * joints
    for group, value in zip(joint_groups(joints), values):
        for j in group:
            out[j] = float(value)
    return out


def group_means(values) -> np.ndarray:
    """The mean of per-joint ``values`` over each joint group of their joints."""
    values = np.asarray(values, dtype=float)
    return np.array([values[list(group)].mean() for group in joint_groups(len(values))])


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
    # Whether the parameters are separate effects of one kind (one per joint or joint group),
    # each of which may be absent: one the data do not move from its nominal value is dropped
    # (``diagnosis.intervals.without_spurious``). Not a payload's centre of mass or a contact's
    # damping ratio: they qualify the cause's other parameters.
    separable: bool = False

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


class JointGroupCause(Cause):
    """A per-joint plant key (``key``) fitted as one value per joint group of an arm of
    ``joints`` joints (``joint_groups``): the drives of one group share a design, so the data
    bound the groups where seven separate values would not be identifiable."""

    key: str = ""
    quantity: str = ""
    unit: str = ""
    separable = True

    def __init__(self, joints: int):
        self.joints = joints
        self.groups = joint_groups(joints)
        self.labels = tuple(f"{self.quantity} {group_name(g)} ({self.unit})" for g in self.groups)

    def nominal_theta(self, nominal):
        return np.maximum(group_means(getattr(nominal.for_joints(self.joints), self.key)), self.lower)

    def overrides(self, theta):
        return {self.key: per_group(theta, self.joints)}

    def theta_of(self, overrides):
        return group_means(overrides[self.key])


class FixedParameters(Cause):
    """``cause`` with some of its parameters held at given values (``held``: index -> theta)
    and only the others (``free``) fitted: a parameter the data do not move from its nominal
    value is dropped from a fit this way (``diagnosis.intervals.without_spurious``)."""

    def __init__(self, cause: Cause, held: dict[int, float]):
        self.cause, self.held = cause, dict(held)
        self.free = tuple(j for j in range(len(cause.labels)) if j not in self.held)
        self.name = cause.name
        self.labels, self.log_scale, self.lower, self.upper = (
            tuple(values[j] for j in self.free) for values in (cause.labels, cause.log_scale, cause.lower, cause.upper)
        )

    def full_theta(self, theta: np.ndarray) -> np.ndarray:
        """Every parameter of ``cause``: the free ones ``theta``, the held ones their values."""
        full = np.zeros(len(self.cause.labels))
        full[list(self.held)] = list(self.held.values())
        full[list(self.free)] = theta
        return full

    def nominal_theta(self, nominal):
        return self.cause.nominal_theta(nominal)[list(self.free)]

    def grid(self, nominal):
        return [self.to_u(self.cause.to_theta(u)[list(self.free)]) for u in self.cause.grid(nominal)]

    def settling_trials(self, index, side, known, normal_speeds):
        return self.cause.settling_trials(self.free[index], side, known, normal_speeds)

    def overrides(self, theta):
        return self.cause.overrides(self.full_theta(theta))

    def theta_of(self, overrides):
        return self.cause.theta_of(overrides)[list(self.free)]
