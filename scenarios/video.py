"""Offscreen rendering of an impact trial as an animated GIF.

MuJoCo picks its OpenGL backend from the environment variable ``MUJOCO_GL`` when it is first
imported: ``egl`` (Debian package libegl1 plus a Mesa or GPU driver) or ``osmesa`` (libosmesa6)
render without a display. Importing this module before anything else imports MuJoCo (the
command line does) makes ``egl`` the default (an explicit MUJOCO_GL wins) and survives a backend
whose libraries are missing: ``import mujoco`` then fails inside PyOpenGL (MUJOCO_GL=osmesa
without libosmesa6 raises AttributeError), so MuJoCo is imported again with rendering disabled
and the failure is kept for :func:`offscreen_backend_problem`, which says in one line why
rendering is impossible, so that a command can refuse ``--video`` before simulating anything.

The video replays the logged joint positions (control rate) from 60 ms before to 60 ms after
the contact, slowed down 10 times, with a camera looking at the contact point along the wall
(the wall is then a line); a G1 trial (``render_humanoid_gif``) likewise, from its logged
configurations. The simulated arm has no geoms (only the tool and the wall collide):
its links are drawn as capsules between the body origins.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")
try:
    import mujoco

    BACKEND_IMPORT_PROBLEM: str | None = None
except Exception as import_error:  # the GL libraries of MUJOCO_GL are missing
    cause: BaseException | None = import_error
    while cause is not None and not isinstance(cause, KeyboardInterrupt):
        cause = cause.__cause__ or cause.__context__
    if cause is not None:  # a stop signal during the import, which an extension's init wrapped
        raise cause from None
    BACKEND_IMPORT_PROBLEM = f"{type(import_error).__name__}: {import_error}"
    for module in [m for m in sys.modules if m.split(".")[0] in ("mujoco", "OpenGL")]:
        del sys.modules[module]
    requested_backend = os.environ["MUJOCO_GL"]
    os.environ["MUJOCO_GL"] = "disable"
    import mujoco

    os.environ["MUJOCO_GL"] = requested_backend

import numpy as np  # noqa: E402

from impactqp.controller.measured.atomic import write_atomic  # noqa: E402
from impactqp.controller.measured.impact import ImpactMeasurement  # noqa: E402
from impactqp.controller.measured.trial_log import TrialLog  # noqa: E402
from impactqp.sim.scene import build_humanoid_scene  # noqa: E402
from impactqp.sim.runner import DEFAULT_CONTROL_PERIOD  # noqa: E402
from impactqp.sim.scene import Scene  # noqa: E402

FRAME_SIZE = (360, 480)  # height, width
SPAN = 0.06
SLOW_MOTION = 10.0
FRAMES_PER_SECOND = 25
LINK_RADIUS = 0.025
HUMANOID_AFTER = 0.3  # s of a G1 trial shown after the contact


def offscreen_backend_problem() -> str | None:
    """None when an offscreen renderer can be created, else a one-line explanation."""
    backend = os.environ.get("MUJOCO_GL", "")
    try:
        if BACKEND_IMPORT_PROBLEM is not None:
            raise RuntimeError(BACKEND_IMPORT_PROBLEM)
        renderer = mujoco.Renderer(mujoco.MjModel.from_xml_string("<mujoco/>"), 16, 16)
    except Exception as error:  # any GL failure means: no usable backend
        first_line = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
        return (
            f"no offscreen OpenGL backend (MUJOCO_GL={backend or 'unset'}: {first_line}); "
            "set MUJOCO_GL=egl (Debian: libegl1) or MUJOCO_GL=osmesa (Debian: libosmesa6)"
        )
    renderer.close()
    return None


def render_impact_gif(scene: Scene, log: TrialLog, impact: ImpactMeasurement, path: str | Path) -> Path:
    """Render the impact of ``log`` (module docstring) to the GIF ``path`` (written atomically)."""
    from PIL import Image

    path = Path(path)
    model = scene.model
    data = mujoco.MjData(model)
    height, width = FRAME_SIZE
    step = 1.0 / (FRAMES_PER_SECOND * SLOW_MOTION * log.control_period)  # samples per frame
    t_c = impact.t_contact_start
    first = int(np.searchsorted(log.t, t_c - SPAN))
    last = int(np.searchsorted(log.t, t_c + SPAN))
    # integer frame indices: a float arange can overshoot its stop by one rounding error
    samples = np.unique(np.minimum(np.arange(first, last, max(step, 1.0)).astype(int), last - 1))

    camera = mujoco.MjvCamera()
    camera.lookat[:] = scene.tool_centre(log.q[impact.pre_index])
    camera.distance = 1.5
    camera.azimuth = 90.0 + float(np.degrees(np.arctan2(scene.surface.normal[1], scene.surface.normal[0])))
    camera.elevation = -15.0
    model.vis.headlight.ambient[:] = 0.5  # the URDF brings no light: a brighter headlight
    frames = []
    with mujoco.Renderer(model, height, width) as renderer:
        for k in samples:
            data.qpos[:] = log.q[k]
            mujoco.mj_forward(model, data)
            renderer.update_scene(data, camera)
            draw_links(renderer.scene, model, data)
            frames.append(Image.fromarray(renderer.render()))
    return save_gif(frames, path)


def save_gif(frames: list, path: Path) -> Path:
    """Write the frames (PIL images) as a looping GIF at FRAMES_PER_SECOND, atomically."""
    return write_atomic(
        path,
        lambda tmp: frames[0].save(
            tmp, format="GIF", save_all=True, append_images=frames[1:], duration=int(1000 / FRAMES_PER_SECOND), loop=0
        ),
    )


def draw_links(scene: mujoco.MjvScene, model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """A capsule from every body's origin to its parent's: the simulated robot has no geoms
    but the tool (only the tool and the wall collide)."""
    for body in range(2, model.nbody):
        if scene.ngeom >= scene.maxgeom:
            return
        geom = scene.geoms[scene.ngeom]
        mujoco.mjv_initGeom(
            geom, mujoco.mjtGeom.mjGEOM_CAPSULE, np.zeros(3), np.zeros(3), np.zeros(9),
            np.array([0.75, 0.75, 0.8, 1.0], dtype=np.float32),
        )
        mujoco.mjv_connector(
            geom, mujoco.mjtGeom.mjGEOM_CAPSULE, LINK_RADIUS,
            data.xpos[model.body_parentid[body]], data.xpos[body],
        )
        scene.ngeom += 1


def render_humanoid_gif(robot, trial, path: str | Path) -> Path:
    """Render a G1 trial (``sim.trial_result.TrialResult`` with held contacts, its logged configurations) to the
    GIF ``path``: from 60 ms before to 300 ms after the first wall contact, slowed down 10 times,
    seen from the side (the wall is a line), the links drawn as capsules between body origins."""
    from PIL import Image

    path = Path(path)
    scene = build_humanoid_scene(robot, trial.held.wall_x)
    model, data = scene.model, scene.data
    height, width = FRAME_SIZE
    step = max(int(round(1.0 / (FRAMES_PER_SECOND * SLOW_MOTION * DEFAULT_CONTROL_PERIOD))), 1)
    first = max(trial.impact.pre_index - int(round(SPAN / DEFAULT_CONTROL_PERIOD)), 0)
    last = min(trial.impact.pre_index + int(round(HUMANOID_AFTER / DEFAULT_CONTROL_PERIOD)), len(trial.held.q_log))
    camera = mujoco.MjvCamera()
    camera.lookat[:] = [trial.held.wall_x - 0.3, 0.0, 0.6]
    camera.distance = 2.6
    camera.azimuth = 90.0
    camera.elevation = -10.0
    model.vis.headlight.ambient[:] = 0.5
    frames = []
    with mujoco.Renderer(model, height, width) as renderer:
        for k in range(first, last, step):
            scene.set_state(trial.held.q_log[k])
            renderer.update_scene(data, camera)
            draw_links(renderer.scene, model, data)
            frames.append(Image.fromarray(renderer.render()))
    return save_gif(frames, path)
