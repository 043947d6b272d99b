"""The impact-aware QP: the controller (``controller``), the problem and where each constraint's
rows sit in it (``problem``), the solver backends (``solvers``), the safe command and the
conflicting constraints (``fallback``), and the ``Command`` it returns (``command``); the
whole-body QP of the standing G1 (``whole_body``) and its set-up (``whole_body_setup``)."""

from .command import Command, Status
from .controller import ImpactAwareController
from .solvers import available_backends
from .whole_body import WholeBodyController
from .whole_body_setup import WholeBodySetup, build_whole_body_controller

__all__ = [
    "Command", "Status", "ImpactAwareController", "available_backends",
    "WholeBodyController", "WholeBodySetup", "build_whole_body_controller",
]
