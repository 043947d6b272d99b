"""The ``replay`` backend: a recorded dataset trial (``controller.measured.dataset``) played
through the loop, for offline checks of the controller, the detector and the watchdog against
real logs. ``read`` returns the logged samples one by one (t, q, dq, and the torque of the period
before, tau[k - 1]; no external-torque estimate); ``write`` keeps the commands; the robot does
not move with them. The trial's force log, when it has one, is the backend's force log."""

from __future__ import annotations

import numpy as np

from impactqp.controller.measured.dataset import DatasetError, DatasetTrial, read_dataset
from impactqp.controller.measured.dataset_check import joint_limit_problem
from impactqp.controller.model.robot_description import robot_description
from impactqp.controller.model.validation import BadInputError

from .interface import RobotInterface, RobotState


def load_trial(directory, trial_id: str | None) -> tuple[DatasetTrial, object]:
    """(trial, dataset header) of ``trial_id`` (the first trial when None); bad input otherwise,
    and for a trial whose joint positions leave the robot's limits (as ``dataset validate``
    finds them). The header's robot and tool (``DatasetHeader.choice``) are what the replay models."""
    try:
        dataset = read_dataset(directory)
    except DatasetError as error:
        raise BadInputError(f"replay dataset {directory}: {error}") from None
    try:
        robot = robot_description(dataset.header.robot)  # a built-in's name or the user's robot file
    except BadInputError as error:
        raise BadInputError(f"replay dataset {directory}: {error}") from None
    if robot.floating:
        raise BadInputError(f"replay dataset {directory}: its robot {robot.name} has a floating base; the replay "
                            "backend plays the logs of fixed-base arms")
    if not dataset.trials:
        raise BadInputError(f"replay dataset {directory} holds no trial")
    chosen = dataset.trials[0] if trial_id is None else next((t for t in dataset.trials if t.entry.id == trial_id), None)
    if chosen is None:
        known = ", ".join(t.entry.id for t in dataset.trials)
        raise BadInputError(f"replay trial {trial_id!r} is not in {directory}; its trials: {known}")
    outside = joint_limit_problem(chosen.log.q, robot, chosen.entry.file)  # no robot reaches such a state
    if outside is not None:
        raise BadInputError(f"replay dataset {directory}: {outside}")
    return chosen, dataset.header


class ReplayRobot(RobotInterface):
    """Plays ``trial`` sample by sample; ``commands`` holds what the loop sent."""

    def __init__(self, trial: DatasetTrial, period: float):
        self.trial = trial
        self.period = float(period)
        self.index = 0
        self.commands: list[np.ndarray] = []

    @property
    def finished(self) -> bool:
        return self.index >= len(self.trial.log)

    def read(self) -> RobotState:
        log = self.trial.log
        k = self.index
        self.index += 1
        # a state reports the torque of the period before it: the log's tau[k - 1]
        return RobotState(float(log.t[k]), log.q[k].copy(), log.dq[k].copy(), log.tau[max(k - 1, 0)].copy())

    def write(self, dq_cmd: np.ndarray) -> None:
        self.commands.append(np.array(dq_cmd, dtype=float))

    def force_log(self) -> tuple[np.ndarray, np.ndarray] | None:
        log = self.trial.log
        return (log.force_t, log.force) if log.has_force else None
