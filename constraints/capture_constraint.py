"""Impact-aware balance: the predicted post-impact centre-of-mass velocity stays inside the
stance's zero-step capture region."""

from __future__ import annotations

import numpy as np
from numba import njit

from impactqp.controller.model.capture import GRAVITY, capture_region
from impactqp.controller.model.jump_kernels import product
from impactqp.controller.model.validation import BadInputError
from impactqp.controller.model.model_terms import ModelTerms

from .constraint import Constraint, ControlCycle
from .impact_model import ExpectedImpact
from .vertex_blocks import VertexBlocks


class CaptureRegionLimit(Constraint):
    """A_cap dc+_xy <= b_cap for the post-impact CoM velocity of the next step.

    The capture region (``controller.model.capture``) of the support ``polygon`` (k edges,
    counter-clockwise) for the CoM at c: rows (nu_k / omega) . dc <= nu_k . (a_k - c), i.e. the
    capture point c + dc / omega stays inside the polygon. With the velocity v' = v + dv s, the
    pre-impact CoM velocity is Jcom v' and the impulse of the expected impact iota = G J v'
    (G of the chosen predictor: crb (12), (20), gm (12), (22), classical (6)), so the
    post-impact CoM velocity is

        dc+ = Jcom v' + C G J v' = K v',    K = Jcom + C G J,    C = Jcom P J^T,

    linear in dv. Each row is multiplied by omega (velocity units) and written at the jerk
    horizon h like the other impact rows, in acceleration units:

        nu_k . K_xy dv <= (omega b_k - nu_k . K_xy v) / h,    omega b_k = omega nu_k . (a_k - c).

    The edges' normals nu_k and offsets nu_k . a_k are the polygon's (``capture_region``, once);
    omega = sqrt(g / (c_z - ground height)) and c follow the CoM every cycle. With non-coplanar
    soles (a foot on a step) the polygon is ``capture.floor_support_polygon`` of the start posture:
    the raised sole's corners projected from the start CoM onto the floor, fixed (the CoM moves
    by centimetres before the impact; docs/floating-base.md, "Non-coplanar soles").

    Simplifications (docs/whole-body-qp.md): the linear-pendulum capture point (constant CoM
    height, no angular momentum); the feet held during the impulse; gm and crb impulses
    frictionless, the classical one sticking. Unbounded while no impact is coming; relaxed to the
    largest correction the cycle allows when the state already violates them.
    """

    relaxed = True

    def __init__(self, impact: ExpectedImpact, polygon: np.ndarray, ground_height: float = 0.0):
        if not impact.held_contacts:
            raise BadInputError("the capture region needs an impact with held contacts (the robot's support)")
        self.impact = impact
        self.polygon = np.asarray(polygon, dtype=float)
        self.ground_height = float(ground_height)
        self.rows = self.polygon.shape[0]
        self.name = f"capture_region[{impact.name}]"
        centre = np.append(self.polygon.mean(axis=0), self.ground_height + 1.0)
        region = capture_region(self.polygon, centre, self.ground_height)  # checks the polygon
        self._normals = region.A * region.omega  # nu_k (k x 2)
        self._offsets = region.b + self._normals @ centre[:2]  # nu_k . a_k

    def kernel_parameters(self) -> np.ndarray:
        """The ground height, the edges' normals nu_k (row by row) and offsets nu_k . a_k."""
        return np.concatenate([[self.ground_height], self._normals.ravel(), self._offsets])

    def compute_into(self, terms: ModelTerms, cycle: ControlCycle, C, lower, upper) -> None:
        lower[:] = -np.inf
        if not self.impact.is_active(terms):
            C[:] = 0.0
            upper[:] = np.inf
            return
        omega = np.sqrt(GRAVITY / (terms.com[2] - self.ground_height))
        maps = self.impact.matrices(terms)
        capture_rows(
            (terms.Jcom, terms.J6, maps.com_map, maps.impulse_map), (terms.com, terms.dq),
            (self._normals, self._offsets), (omega, 1.0 / cycle.horizon), C, upper,
        )


@njit(cache=True)
def capture_rows(maps, state, region, scale, C, upper):
    """Kernel: C = nu K_xy, K_xy = Jcom_xy + (C_xy G) J (the class docstring), and
    upper = (omega (nu . a - nu c_xy) - C v) / h, for maps = (Jcom, J6, C, G), state = (c, v),
    region = (nu, nu . a) and scale = (omega, 1 / h)."""
    Jcom, J6, com_map, impulse_map = maps
    com, dq = state
    normals, offsets = region
    omega, inv_h = scale
    K = Jcom[:2] + product(product(com_map[:2], impulse_map), J6[:3])
    C[:] = product(normals, K)
    for k in range(C.shape[0]):
        speed = 0.0  # C v, in a loop: a BLAS call costs more at this size
        for j in range(dq.shape[0]):
            speed += C[k, j] * dq[j]
        upper[k] = (omega * (offsets[k] - normals[k, 0] * com[0] - normals[k, 1] * com[1]) - speed) * inv_h


class EdgeCaptureRegionLimit(VertexBlocks, CaptureRegionLimit):
    """The capture region's rows of :class:`CaptureRegionLimit` for the frictionless impulse,
    then the same rows for each edge impulse of the impact's friction rows (``ExpectedImpact``
    with ``FrictionRows``, docs/frictional-impacts.md): the post-impact CoM velocity of every
    vertex of the friction-cone section the impulse may take,

        dc+_i = Jcom v' + C G_i J v',    G_i = -(1 + c_r) d_i n^T / (n^T W d_i)

    (``friction_pyramid.edge_impulse_maps``, with its guard), inside the capture region; being
    linear in the impulse at a given v', the rows then hold for every convex combination of the
    vertices. (1 + edges) x polygon edges rows; without friction, the rows of
    :class:`CaptureRegionLimit` alone."""

    def __init__(self, impact: ExpectedImpact, polygon: np.ndarray, ground_height: float = 0.0):
        super().__init__(impact, polygon, ground_height)
        self.stack_vertices()
        self.name = f"capture_region_edges[{impact.name}]"

    def vertex_rows_into(self, terms: ModelTerms, cycle: ControlCycle, impulse_map, C, upper) -> None:
        omega = np.sqrt(GRAVITY / (terms.com[2] - self.ground_height))
        capture_rows(
            (terms.Jcom, terms.J6, self.impact.matrices(terms).com_map, impulse_map), (terms.com, terms.dq),
            (self._normals, self._offsets), (omega, 1.0 / cycle.horizon), C, upper,
        )
