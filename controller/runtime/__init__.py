"""The robot runtime (``docs/robot-loop.md``): the robot interface, the 1 kHz loop runner with its
watchdog and command filter, the impact session (controller, online impact detection and
post-impact phase), the run log, the move to the start posture, and the backends of what this
layer can reach (``franka``: an FR3 through pylibfranka; ``panda``: a Panda through
panda-python's libfranka 0.9; both imported only when chosen, their shared settings, model check
and statistics in ``libfranka_robot``; ``replay``: a measured trial). The MuJoCo backend sits
with the simulation (``sim.sim_backend``). It imports no MuJoCo."""
