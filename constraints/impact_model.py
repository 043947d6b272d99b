"""The impact the impact-aware constraints prepare for (``ExpectedImpact``): surface, jump model,
activation rule, and the jump of the measured velocity that shows it happened (``shows_jump``:
the controller's impact brake and a standing robot's session both read it), for any robot (a
fixed-base arm, or a humanoid on held contacts).

Jump prediction (docs/qp-constraints.md). With the pre-impact velocity dq- = dq + ddq dt, the
chosen predictor (``controller.model.jump``, ``JumpModel.unit_matrices``) gives an impulse
iota = G J dq- and a velocity jump ddq_jump = K iota = A dq-, A = K G J, both linear in dq-:

    crb        (12), (20)-(21)   G = -(1+c_r) n n^T / (n^T W_crb n),   K = J+ W_crb
    gm         (12), (22)-(23)   G = -(1+c_r) n n^T / (n^T W_gm n),    K = J+ W_gm
    classical  (5)-(6)           G = -(1+c_r) (J M^-1 J^T)^-1,         K = M^-1 J^T

(with held contacts Jf, M^-1 becomes P_f = M^-1 - M^-1 Jf^T (Jf M^-1 Jf^T)^-1 Jf M^-1 and J+ the
held-contact right inverse J#, and the centre of mass jumps by C iota: ``jump``'s docstring).
The post-impact velocity is dq+ = (I + A) dq- and the impulsive joint torque over the impact
duration delta_t is J^T iota / delta_t = P dq- / delta_t with P = J^T G J.

Friction rows
-------------
With ``FrictionRows`` of friction mu > 0 (``controller.model.friction_pyramid``), the impact also
carries the edges' maps A_i = K G_i J and P_i = J^T G_i J of the friction pyramid (or of the
one-step preview's three: its sector or the 3-edge pyramid), computed once per fill of the terms
(``edge_matrices``); the post-impact-velocity and impulsive-torque rows stack them under the
frictionless ones. Not with ``classical_normal``. On held contacts (a humanoid's soles) the
edges' maps are the predictor's held-contact ones (``friction_pyramid.held_edge_maps_into``),
and the edge impulse maps G_i (``edge_impulse_maps``) feed the capture region's and the feet's
rows of every edge (``capture_constraint.EdgeCaptureRegionLimit``,
``foot_wrench.EdgeFootWrenchLimit``).

Activation rule
---------------
The constraints only describe an impact that is about to happen. They are active in a cycle
when the contact point is not leaving the surface (normal velocity n.v <= release_speed, with
v = J dq) and the surface is near: the signed distance d of the contact point satisfies
d <= lookahead_distance, or d <= lookahead_time * max(-n.v, 0) (the impact would come within
lookahead_time at the current speed). ``always_active=True`` bypasses the rule. Because one
cycle changes the contact velocity by at most |J| ddq_max dt (a few mm/s), a cycle in which the
rule says inactive cannot command a dangerous approach speed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from impactqp.controller.model.friction_pyramid import (
    EdgeMatrices,
    Edges,
    FrictionRows,
    edge_directions,
    edge_inverse_inertia,
    fill_edge_matrices,
    held_edge_maps_into,
    held_response_maps,
    slip_edges_into,
)
from impactqp.controller.model.jump import (
    ClassicalJump,
    CompositeRigidBodyJump,
    GeneralizedMomentumJump,
    JumpMatrices,
    JumpModel,
    jump_model,
)
from impactqp.controller.model.jump_kernels import HELD_CONTACT_METHODS, held_contact_maps_into
from impactqp.controller.model.postures import Surface
from impactqp.controller.model import validation
from impactqp.controller.model.validation import BadInputError

from .impact_cycle_kernels import (
    CLASSICAL,
    CRB,
    GM,
    activation,
    classical_cycle_update,
    crb_cycle_update,
    fixed_base_matrix_views,
    gm_cycle_update,
    normal_motion,
)

MAX_LOOKAHEAD_DISTANCE, MAX_LOOKAHEAD_TIME = 1.0, 10.0
"""m and s: the impact-aware constraints switch on within a metre or ten seconds of the surface."""

JUMP_MODEL_CHOICES = {
    "crb": ("crb",),
    "gm": ("gm",),
    "classical": ("classical",),
    "classical_normal": ("classical_normal",),
    "robust": ("crb", "gm", "classical"),
}
"""Jump-model settings of the impact-aware constraints; 'robust' satisfies crb, gm and
classical at once."""


def jump_model_names(choice: str) -> tuple[str, ...]:
    try:
        return JUMP_MODEL_CHOICES[choice]
    except KeyError:
        raise BadInputError(
            f"unknown jump model {choice!r}; choose from {', '.join(JUMP_MODEL_CHOICES)}"
        ) from None


@dataclass(frozen=True)
class ActivationRule:
    """The activation rule of the module docstring: on within ``lookahead_distance`` (m) or
    ``lookahead_time`` (s) of the surface while the contact's normal velocity is at most
    ``release_speed`` (m/s); always on with ``always_active``."""

    lookahead_distance: float = 0.10
    lookahead_time: float = 0.30
    release_speed: float = 0.02
    always_active: bool = False

    def __post_init__(self):
        validation.number_in_range(self.lookahead_distance, 0.0, MAX_LOOKAHEAD_DISTANCE, "the look-ahead distance", "m")
        validation.number_in_range(self.lookahead_time, 0.0, MAX_LOOKAHEAD_TIME, "the look-ahead time", "s")
        validation.number_in_range(self.release_speed, 0.0, validation.MAX_CONTACT_SPEED, "the release speed", "m/s")
        validation.boolean(self.always_active, "always_active")


IMPACT_SPEED_DROP = 0.5
"""An impact shows when the measured speed of the contact point towards the surface falls below
this fraction of the commanded one (``ExpectedImpact.shows_jump``)."""
RELEASED, FOLLOWING, DROPPED = 0, 1, 2  # ``ExpectedImpact.speed_tracking``'s answers


class ExpectedImpact:
    """An expected impact on ``surface`` predicted with one jump model: the jump matrices of a
    state and whether the impact-aware rows apply to it (the activation rule), both computed
    once per fill of the model terms (their ``stamp``: the ``ModelTerms`` of any robot) and
    shared by the constraints and the controller's
    prediction. ``held_contacts`` says the robot stands on held contacts (its terms'
    ``held_jacobian`` has rows): then only the models of ``jump_kernels.HELD_CONTACT_METHODS``
    apply (the others are bad input, here rather than at the first cycle)."""

    def __init__(
        self,
        surface: Surface,
        jump_model_name: str = "crb",
        restitution: float = 0.0,
        rule: ActivationRule = ActivationRule(),
        held_contacts: bool = False,
        friction: FrictionRows = FrictionRows(),
    ):
        self.held_contacts = validation.boolean(held_contacts, "held_contacts")
        if self.held_contacts and jump_model_name not in HELD_CONTACT_METHODS:
            raise BadInputError(
                f"unknown jump model {jump_model_name!r} with held contacts; "
                f"choose from {', '.join(HELD_CONTACT_METHODS)}"
            )
        self.surface = surface
        self.model: JumpModel = jump_model(jump_model_name)
        self.restitution = validation.restitution(restitution)
        if not isinstance(rule, ActivationRule) or not isinstance(friction, FrictionRows):
            raise TypeError("rule must be an ActivationRule and friction a FrictionRows")
        self.friction = friction
        if friction.count and jump_model_name == "classical_normal":
            raise BadInputError("friction rows are for the crb, gm or classical model, not classical_normal")
        self._surface_offset = float(surface.normal @ surface.point)  # n.s: distance = n.p - n.s
        self._impact = np.append(np.asarray(surface.normal, dtype=float), self.restitution)  # [n, c_r]
        self.rule = rule  # and its values (``rule_values``)
        self._stamp = 0  # ModelTerms.stamp of the cached matrices and activation
        self._matrices: JumpMatrices | None = None
        self._views: JumpMatrices | None = None  # what ``matrices`` returns
        self._active = False
        directions = edge_directions(friction, surface.normal, np.zeros(3), np.eye(3), 0.0)  # the preview's: per state
        self._uncertain = directions.copy()  # the preview's edges while its slip is uncertain
        self._edge_set = Edges(directions, np.array(surface.normal, dtype=float), float(self.restitution))
        self._edge_count = friction.count
        self._edge_buffer = np.empty((2, 0, 0, 0))  # A_i and P_i, allocated at the first state
        self._edges, self._edge_views = edge_maps_of(self._edge_buffer)
        self._edge_impulses = np.empty((friction.count, 3, 3))  # G_i, on held contacts
        self._edge_impulse_views = read_only(self._edge_impulses)  # what ``edge_impulse_maps`` returns
        self._edge_fill = self._fill_held_edges if self.held_contacts else self._fill_edges
        # The crb, gm and classical models of a fixed base write A, P and G into one buffer,
        # allocated at the first fill (``_fill_fixed_base``) or a plan's (``fill_stacked``); the
        # other forms return new matrices.
        model = self.model
        self._in_place = isinstance(model, GeneralizedMomentumJump) or type(model) is ClassicalJump
        self._map_buffer = np.empty(0)
        self._fixed_base_matrices = self._fixed_base_views = JumpMatrices(None, None, None, None)
        # On held contacts: A, P, G, C and the held contacts' impulse map Z, allocated at the first fill
        held_method = jump_model_name in HELD_CONTACT_METHODS
        self._held_method = HELD_CONTACT_METHODS.index(jump_model_name) if held_method else -1
        self._held_buffers: tuple = (None, None, None, None, np.empty((0, 3)))
        self._held_matrices = self._held_views = self._fixed_base_matrices

    rule_edits = 0
    """Assignments to any impact's ``rule`` so far: a compiled plan that reads the rule values packs
    them again when it changed (``cycle_plan``)."""

    @property
    def rule(self) -> ActivationRule:
        return self._rule_object

    @rule.setter
    def rule(self, rule: ActivationRule) -> None:
        if not isinstance(rule, ActivationRule):
            raise TypeError("rule must be an ActivationRule")
        self._rule_object = rule
        model = self.model
        kind = CRB if isinstance(model, CompositeRigidBodyJump) else CLASSICAL if type(model) is ClassicalJump else GM
        self.rule_values = np.concatenate([self._impact, [
            float(rule.always_active), rule.release_speed, rule.lookahead_distance, rule.lookahead_time,
            self._surface_offset, kind,
        ]])  # ``impact_cycle_kernels.RULE_VALUES``: what the compiled rule and a plan's update read
        ExpectedImpact.rule_edits += 1

    @property
    def name(self) -> str:
        return self.model.name

    @property
    def plan_updates_it(self) -> bool:
        """Whether a compiled plan updates this impact in its own kernel (``stacked_updates``): the
        crb, gm or classical model of a fixed base, without friction rows or with a pyramid's (whose
        edge directions do not change); the plan then tells it so (``adopt_stacked``)."""
        edges_fixed = not self._edge_count or self.friction.mode == "pyramid"
        return self._in_place and not self.held_contacts and edges_fixed

    def plan_values(self) -> np.ndarray:
        """What a compiled plan's kernel reads of this impact (``stacked_updates``): its rule
        values, then its edges' directions (edges x 3, row by row)."""
        return np.concatenate([self.rule_values, np.ravel(self._edge_set.directions)])

    def matrices(self, terms) -> JumpMatrices:
        """A, P, G (and C) of this state (the normal and the restitution were checked once, above),
        valid until the next fill of the terms: the crb, gm and classical matrices (of a fixed
        base, or on held contacts) are read-only views of buffers that the next fill overwrites
        (copy them to keep them); the other forms are new arrays at each fill."""
        if terms.stamp != self._stamp:  # a new fill of the terms (read several times per cycle)
            self._update(terms)
        return self._views

    def row_matrices(self, terms) -> JumpMatrices:
        """``matrices`` as the arrays themselves, writable, for the compiled row kernels of the
        constraints that read them within the cycle (a read-only array makes each compiled call's
        dispatch slower)."""
        if terms.stamp != self._stamp:
            self._update(terms)
        return self._matrices

    def edge_matrices(self, terms) -> EdgeMatrices:
        """A_i and P_i of the friction rows' edges at this state (``friction.count`` of them;
        none without friction), valid until the next fill of the terms: read-only views of the
        buffer that the next fill overwrites (copy them to keep them), as ``matrices``."""
        if terms.stamp != self._stamp:
            self._update(terms)
        return self._edge_views

    def edge_row_matrices(self, terms) -> EdgeMatrices:
        """``edge_matrices`` as the buffer itself, writable, for the compiled row kernels that read
        it within the cycle (as ``row_matrices``)."""
        if terms.stamp != self._stamp:
            self._update(terms)
        return self._edges

    def edge_impulse_maps(self, terms) -> np.ndarray:
        """G_i (edges x 3 x 3) of the friction rows' edges at this state on held contacts: the
        edge impulses iota_i = G_i J dq- (``friction_pyramid.edge_impulse_maps``), valid until the
        next fill of the terms: a read-only view of the buffer that the next fill overwrites (copy
        it to keep it), as ``edge_matrices``."""
        if terms.stamp != self._stamp:
            self._update(terms)
        return self._edge_impulse_views

    def edge_row_impulse_maps(self, terms) -> np.ndarray:
        """``edge_impulse_maps`` as the buffer itself, writable, for the compiled row kernels that
        read it within the cycle (as ``row_matrices``)."""
        if terms.stamp != self._stamp:
            self._update(terms)
        return self._edge_impulses

    def held_impulse_map(self, terms) -> np.ndarray:
        """Z = (Jf M^-1 Jf^T)^-1 Jf M^-1 J^T (6 rows per held contact x 3) of this state: the held
        contacts' impulsive wrenches lambda = -Z iota (``jump.held_impulse``), computed with the
        jump maps (``jump_kernels.held_contact_maps_into``; no rows without held contacts); valid
        until the next fill of the terms, as ``row_matrices``."""
        if terms.stamp != self._stamp:
            self._update(terms)
        return self._held_buffers[4]

    def is_active(self, terms) -> bool:
        """The activation rule of the module docstring for this state."""
        if terms.stamp != self._stamp:
            self._update(terms)
        return self._active

    def fill_stacked(self, terms, maps: np.ndarray, edges: np.ndarray) -> bool:
        """This state's A, P, G in ``maps`` (flat [A, P, G]: ``fixed_base_matrix_views``, at
        least 2 n^2 + 9 values) and its edges' A_i, P_i in ``edges`` (2 x edges x n x n): one
        impact's rows of a compiled plan's stacked buffers; its activation. The first call with
        new buffers makes them this impact's own (a fixed base's crb, gm and classical fills and
        the edges' fills write into them, no copy); the other forms' new matrices are copied in."""
        self.own_stacked(maps, edges)
        if terms.stamp != self._stamp:
            self._update(terms)
            matrices = self._matrices
            if matrices is not self._fixed_base_matrices:  # a form that returns new matrices
                self._fixed_base_matrices.jump_matrix[:] = matrices.jump_matrix
                self._fixed_base_matrices.torque_matrix[:] = matrices.torque_matrix
        return self._active

    def own_stacked(self, maps: np.ndarray, edges: np.ndarray) -> None:
        """Make a compiled plan's stacked buffers (``fill_stacked``'s) this impact's own, unless they
        are already: its fixed-base and edge fills write into them from then on."""
        if maps is not self._map_buffer or edges is not self._edge_buffer:
            n = edges.shape[-1]
            self._map_buffer, self._edge_buffer = maps, edges
            self._fixed_base_matrices = JumpMatrices(*fixed_base_matrix_views(maps, n), None)
            self._fixed_base_views = read_only_views(self._fixed_base_matrices)
            self._edges, self._edge_views = edge_maps_of(edges)
            self._stamp = 0  # refilled into them now

    def adopt_stacked(self, terms, active: bool, maps: np.ndarray, edges: np.ndarray) -> None:
        """A compiled plan's kernel (``stacked_updates``) wrote the terms' A, P and G into its
        stacked buffers ``maps`` (and ``edges``), made this impact's own (``own_stacked``), and found
        its activation ``active``."""
        self.own_stacked(maps, edges)
        self._matrices, self._views = self._fixed_base_matrices, self._fixed_base_views
        self._active, self._stamp = active, terms.stamp

    def shows_jump(self, J: np.ndarray, dq: np.ndarray, dq_cmd: np.ndarray) -> bool:
        """Whether the velocity dq shows the impact's jump against the command dq_cmd (both at the
        contact Jacobian J): the commanded speed towards the surface, -n.(J dq_cmd), is above the
        release speed and the measured one, -n.(J dq), below ``IMPACT_SPEED_DROP`` times it (the
        predicted jump takes it to -c_r times itself within the contact's few milliseconds; a
        joint servo's tracking error is far smaller)."""
        return self.speed_tracking(J, dq, dq_cmd) == DROPPED

    def speed_tracking(self, J: np.ndarray, dq: np.ndarray, dq_cmd: np.ndarray) -> int:
        """How the measured speed towards the surface follows the commanded one (``shows_jump``):
        :data:`RELEASED` (the command below the release speed), :data:`DROPPED` (the measured
        below ``IMPACT_SPEED_DROP`` times the commanded) or :data:`FOLLOWING`."""
        normal, point = self.surface.normal, self.surface.point
        commanded = -normal_motion(J, normal, point, dq_cmd)[0]
        if not commanded > self.rule.release_speed:
            return RELEASED
        return DROPPED if -normal_motion(J, normal, point, dq)[0] < IMPACT_SPEED_DROP * commanded else FOLLOWING

    def _update(self, terms) -> None:
        """The matrices, edges and activation of the fill ``terms.stamp``."""
        normal = self.surface.normal
        if self._in_place and terms.held_jacobian.shape[0] == 0:
            motion = self._fill_fixed_base(terms)
        else:
            if terms.held_jacobian.shape[0] and self._held_method >= 0:
                self._fill_held(terms)
            else:
                self._matrices = self._views = self.model.unit_matrices(terms, normal, self.restitution)
            motion = normal_motion(terms.J, normal, terms.contact_point, terms.dq)
        if self._edge_count:
            self._edge_fill(terms)
        self._active = activation(self.rule_values, *motion)
        self._stamp = terms.stamp

    def _fill_fixed_base(self, terms) -> tuple[float, float]:
        """A, P and G of a fixed base's crb, gm or classical model (their ``fixed_base_matrices``:
        the rank-one products of ``jump`` or ``classical_jump_matrices``) written into the buffer,
        and the activation rule's n.(J dq) and n.p, in one compiled call of flat array arguments
        (the terms' ``contact_terms``, [n, c_r], the buffer [A, P, G]); the buffer is allocated
        at the first fill."""
        n = terms.J.shape[1]
        out = self._map_buffer
        if out.shape[0] < 2 * n * n + 9:
            out = self._map_buffer = np.empty(2 * n * n + 9)
            self._fixed_base_matrices = JumpMatrices(*fixed_base_matrix_views(out, n), None)
            self._fixed_base_views = read_only_views(self._fixed_base_matrices)
        self._matrices, self._views = self._fixed_base_matrices, self._fixed_base_views
        contact, impact = terms.contact_terms, self._impact
        if isinstance(self.model, CompositeRigidBodyJump):
            return crb_cycle_update(contact, terms.com, terms.inertia_com, terms.mass, terms.dq, impact, out)
        if isinstance(self.model, ClassicalJump):
            return classical_cycle_update(terms.M_inv, contact, terms.dq, impact, out)
        return gm_cycle_update(terms.M_inv, contact, terms.dq, impact, out)

    def _fill_held(self, terms) -> None:
        """On held contacts: A, P, G, C of the crb, gm or classical model and the held contacts'
        impulse map Z written into buffers allocated at the first fill (or when the sizes change),
        in one compiled call (``jump_kernels.held_contact_maps_into``)."""
        nv, held = terms.J.shape[1], terms.held_jacobian.shape[0]
        jump_matrix, held_impulses = self._held_buffers[0], self._held_buffers[4]
        if jump_matrix is None or jump_matrix.shape[0] != nv or held_impulses.shape[0] != held:
            square, small = (nv, nv), (3, 3)
            self._held_buffers = (np.empty(square), np.empty(square), np.empty(small), np.empty(small), np.empty((held, 3)))
            self._held_matrices = JumpMatrices(*self._held_buffers[:4])
            self._held_views = JumpMatrices(*(read_only(array) for array in self._held_buffers[:4]))
        self._matrices, self._views = self._held_matrices, self._held_views
        rigid = (terms.contact_point, terms.com, terms.inertia_com, terms.mass)
        held_contact_maps_into(
            (terms.M_inv, terms.J6, terms.held_jacobian, terms.Jcom), rigid, self._held_method,
            (self._impact[:3], self._impact[3]), self._held_buffers,
        )

    def _fill_edges(self, terms) -> None:
        """The edges' maps of this state into buffers allocated at the first fill (the preview's
        edge directions first, from this state's contact velocity)."""
        n = terms.J.shape[1]
        edges = self._edge_set
        if self._edge_buffer.shape != (2, count := edges.directions.shape[0], n, n):
            self._edge_buffer = np.empty((2, count, n, n))
            self._edges, self._edge_views = edge_maps_of(self._edge_buffer)
        W = edge_inverse_inertia(self.model, terms)
        if self.friction.mode == "slip":
            edges.directions[:] = self._uncertain
            slip_edges_into(terms.J @ terms.dq, W, edges.normal, self.friction.friction, edges.restitution, edges.directions)
        fill_edge_matrices(self.model, terms, W, edges, self._edge_buffer)

    def _fill_held_edges(self, terms) -> None:
        """On held contacts: the edges' maps and impulse maps G_i of this state (the preview's
        directions first), with the predictor's held-contact K and W."""
        edges, nv = self._edge_set, terms.J.shape[1]
        if self._edge_buffer.shape[-1] != nv:  # the first fill
            self._edge_buffer = np.empty((2, self._edge_count, nv, nv))
            self._edges, self._edge_views = edge_maps_of(self._edge_buffer)
        response = held_response_maps(self.model, terms, edges.normal, edges.restitution)
        if self.friction.mode == "slip":
            edges.directions[:] = self._uncertain
            slip_edges_into(terms.J @ terms.dq, response[1], edges.normal, self.friction.friction, edges.restitution,
                            edges.directions)
        held_edge_maps_into(response, terms.J, edges, self._edge_buffer, self._edge_impulses)


def read_only_views(matrices: JumpMatrices) -> JumpMatrices:
    """Views of A, P and G that cannot be written (the buffers behind them stay writable)."""
    return JumpMatrices(*(read_only(array) for array in matrices[:3]), None)


def read_only(array: np.ndarray) -> np.ndarray:
    """A view of ``array`` that cannot be written (the array itself stays writable)."""
    view = array.view()
    view.flags.writeable = False
    return view


def edge_maps_of(buffer: np.ndarray) -> tuple[EdgeMatrices, EdgeMatrices]:
    """The edges' maps in ``buffer`` (2 x edges x nv x nv), writable, and read-only views of them."""
    return EdgeMatrices.of(buffer), EdgeMatrices.of(read_only(buffer))
