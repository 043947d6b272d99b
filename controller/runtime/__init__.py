"""The robot runtime (``docs/robot-loop.md``): the robot interface, the 1 kHz loop runner with its
watchdog and command filter, the impact session (controller, online impact detection and
post-impact phase), the run log, and the backends of what this layer can reach (``franka``:
pylibfranka, imported only when chosen; ``replay``: a measured trial). The MuJoCo backend sits
with the simulation (``sim.sim_backend``). It imports no MuJoCo."""
