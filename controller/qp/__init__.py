"""The impact-aware QP: the controller of every robot, fixed or floating base (``controller``,
its compiled kernels in ``cycle_kernels``, every task and constraint row in one compiled call in
``cycle_plan``), the problem and where each constraint's rows sit in
it (``problem``), the solver backends (``solvers``), the safe command and the conflicting
constraints (``fallback``), and the ``Command`` it returns (``command``)."""

from .command import Command, Status
from .controller import ImpactAwareController
from .solvers import available_backends

__all__ = [
    "Command", "Status", "ImpactAwareController", "available_backends",
]
