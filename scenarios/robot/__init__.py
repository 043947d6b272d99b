"""Plugging the controller into a 1 kHz robot loop (``docs/robot-loop.md``): the robot
interface and its backends (``sim``, ``franka``, ``replay``), the impact session (controller,
online impact detection and post-impact phase) and the loop runner with its watchdog."""
