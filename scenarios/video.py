"""Offscreen rendering of an impact trial, with the robot's own meshes, as an animated GIF.

MuJoCo picks its OpenGL backend from the environment variable ``MUJOCO_GL`` when it is first
imported: ``egl`` (Debian package libegl1 plus a Mesa or GPU driver) or ``osmesa`` (libosmesa6)
render without a display. Importing this module before anything else imports MuJoCo (the
command line does) makes ``egl`` the default (an explicit MUJOCO_GL wins) and survives a backend
whose libraries are missing: ``import mujoco`` then fails inside PyOpenGL (MUJOCO_GL=osmesa
without libosmesa6 raises AttributeError), so MuJoCo is imported again with rendering disabled
and the failure is kept for :func:`offscreen_backend_problem`, which says in one line why
rendering is impossible, so that a command can refuse ``--video`` before simulating anything.

The video (:func:`render_trial_video`) replays a trial's logged configurations on the render
model of its scene (``sim.render_scene``: the robot's meshes, the tool and the wall, the scene's
qpos layout): at real time from :data:`BEFORE` before the contact, slowed down
:data:`SLOW_MOTION` times within +-:data:`SPAN` of it, at real time again up to the trial's
``after`` (:func:`frame_samples`). The arm is seen along the wall (the wall is a line), the
standing G1 from the side. Each frame carries the overlay of :func:`overlay_lines`: the time
relative to the contact (ms) and the playback speed, the contact speed, and for the binding
joint (the largest predicted |dq+_i| / dq_max_i, CRB) its |dq| now, its limit and its CRB
prediction dq+ = dq- + Delta dq (eq. (19)). The output format follows the file suffix
(:data:`VIDEO_SUFFIXES`: ``.gif``, written with PIL).
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
from impactqp.controller.model.validation import BadInputError  # noqa: E402
from impactqp.sim.render_scene import RenderScene, arm_render_scene, humanoid_render_scene  # noqa: E402
from impactqp.sim.scene import TOOL_GEOM  # noqa: E402

FRAME_SIZE = (360, 480)  # height, width
SPAN = 0.06  # s: the slow-motion window on either side of the contact
SLOW_MOTION = 10.0
BEFORE = 0.3  # s shown before the contact
ARM_AFTER = 0.12  # s of an arm trial shown after the contact
HUMANOID_AFTER = 0.3  # s of a G1 trial shown after the contact
FRAMES_PER_SECOND = 25
VIDEO_SUFFIXES = (".gif",)
OVERLAY_METHOD = "crb"
SHOULDER = np.array([0.0, 0.0, 0.45])  # m: a point above an arm's base the camera keeps in view
OFFSCREEN_SAMPLES = 0
"""Multisampling of the offscreen frames (``visual/quality/offsamples``, MuJoCo's default 4): off,
since a software renderer (Mesa's llvmpipe behind EGL on a machine without a GPU) spends more
than half of each frame on it, and a GIF's 256 colours hide the jagged edges it smooths."""


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


def check_video_suffix(path: str | Path, what: str = "--video") -> Path:
    """``path`` when its suffix names a format of :data:`VIDEO_SUFFIXES`, else bad input."""
    path = Path(path)
    if path.suffix.lower() not in VIDEO_SUFFIXES:
        raise BadInputError(
            f"{what} writes an animated GIF: give a {' or '.join(VIDEO_SUFFIXES)} file name, got {str(path)!r}"
        )
    return path


def frame_samples(t: np.ndarray, t_contact: float, after: float) -> np.ndarray:
    """The control samples shown, one per frame at :data:`FRAMES_PER_SECOND`: the frame times
    advance by 1/fps of trial time outside the window |t - t_contact| <= SPAN and by
    1/(fps SLOW_MOTION) inside it (which a real-time step does not skip into: it stops at its
    start), from t_contact - BEFORE to t_contact + ``after`` (clipped to the log); each time is
    shown by the last sample at or before it."""
    real, slow = 1.0 / FRAMES_PER_SECOND, 1.0 / (FRAMES_PER_SECOND * SLOW_MOTION)
    start, stop = max(t_contact - BEFORE, float(t[0])), min(t_contact + after, float(t[-1]))
    times, now = [], start
    while now <= stop:
        times.append(now)
        if t_contact - SPAN - 1e-9 <= now < t_contact + SPAN:
            now += slow
        else:  # a real-time step lands on the window's start rather than inside it
            now = t_contact - SPAN if now < t_contact - SPAN < now + real else now + real
    return np.unique(np.clip(np.searchsorted(t, times, side="right") - 1, 0, len(t) - 1))


def shown_samples(trial) -> np.ndarray:
    """The samples of ``trial`` a video shows (:func:`frame_samples`: an arm's up to ARM_AFTER, a
    standing robot's up to HUMANOID_AFTER after the contact)."""
    after = HUMANOID_AFTER if trial.held is not None else ARM_AFTER
    return frame_samples(trial.log.t, trial.impact.t_contact_start, after)


def configurations_of(trial) -> np.ndarray:
    """The logged Pinocchio configurations of ``trial`` per control sample (a floating base's
    with its base pose)."""
    return trial.held.q_log if trial.held is not None else trial.log.q


def binding_joint(trial, dq_max: np.ndarray) -> int:
    """The joint whose predicted post-impact speed |dq- + Delta dq| (OVERLAY_METHOD, eq. (19)) is
    the largest fraction of its limit."""
    return int(np.argmax(np.abs(trial.predicted_post_velocity(OVERLAY_METHOD)) / dq_max))


def overlay_lines(trial, robot, k: int) -> list[str]:
    """The overlay of control sample ``k`` (module docstring) of ``trial`` of the robot ``robot``
    (its description: joint names and limits)."""
    joints, dq_max = robot.joints, robot.dq_max
    t = float(trial.log.t[k] - trial.impact.t_contact_start)
    pace = f"{SLOW_MOTION:g}x slow motion" if abs(t) < SPAN else "real time"
    j = binding_joint(trial, dq_max)
    post = trial.predicted_post_velocity(OVERLAY_METHOD)[j]
    return [
        f"t - t_contact = {t * 1e3:+7.1f} ms   ({pace})",
        f"contact speed {trial.contact_speed:.3f} m/s",
        f"{joints[j]}: |dq| {abs(trial.log.dq[k, j]):.3f} rad/s, limit {dq_max[j]:.3f}, "
        f"{OVERLAY_METHOD.upper()} dq+ {post:+.3f}",
    ]


def draw_overlay(image, lines: list[str]):
    """The frame ``image`` (PIL) with ``lines`` written in white on a dark band at its top."""
    from PIL import ImageDraw, ImageFont

    font = ImageFont.load_default(size=max(10, image.height // 30))
    draw = ImageDraw.Draw(image)
    line_height = font.size + 3
    draw.rectangle([0, 0, image.width, 6 + line_height * len(lines)], fill=(20, 24, 32))
    for i, line in enumerate(lines):
        draw.text((6, 3 + i * line_height), line, fill=(255, 255, 255), font=font)
    return image


def arm_camera(render: RenderScene, q: np.ndarray) -> mujoco.MjvCamera:
    """A camera looking along the wall at the middle between the tool at the configuration ``q``
    and the arm's shoulder (:data:`SHOULDER`)."""
    model, data = render.model, mujoco.MjData(render.model)
    data.qpos[:] = render.qpos(q)
    mujoco.mj_kinematics(model, data)
    camera = mujoco.MjvCamera()
    camera.lookat[:] = 0.5 * (data.geom_xpos[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, TOOL_GEOM)] + SHOULDER)
    camera.distance = 1.5
    normal = render.surface.normal
    camera.azimuth = 90.0 + float(np.degrees(np.arctan2(normal[1], normal[0])))
    camera.elevation = -12.0
    return camera


def humanoid_camera(render: RenderScene) -> mujoco.MjvCamera:
    """A camera looking at the standing robot from its side (the wall is a line)."""
    camera = mujoco.MjvCamera()
    camera.lookat[:] = [render.surface.point[0] - 0.3, 0.0, 0.6]
    camera.distance = 2.6
    camera.azimuth = 90.0
    camera.elevation = -10.0
    return camera


def render_frames(render: RenderScene, trial, camera: mujoco.MjvCamera, samples, frame_size=FRAME_SIZE) -> list:
    """The frames (PIL images) of the control ``samples`` of ``trial`` on ``render``, with their
    overlays."""
    from PIL import Image

    configurations = configurations_of(trial)
    model, data = render.model, mujoco.MjData(render.model)
    model.vis.quality.offsamples = OFFSCREEN_SAMPLES
    height, width = frame_size
    frames = []
    with mujoco.Renderer(model, height, width) as renderer:
        for k in samples:
            data.qpos[:] = render.qpos(configurations[k])
            mujoco.mj_kinematics(model, data)
            renderer.update_scene(data, camera)
            frames.append(draw_overlay(Image.fromarray(renderer.render()), overlay_lines(trial, render.robot, k)))
    return frames


def render_trial_video(render: RenderScene, trial, path: str | Path, frame_size=FRAME_SIZE) -> Path:
    """Render ``trial`` (``sim.trial_result.TrialResult``, an arm's or a standing robot's) on the
    render model of its scene to the video ``path`` (module docstring), written atomically."""
    path = check_video_suffix(path)
    samples = shown_samples(trial)
    if trial.held is not None:
        camera = humanoid_camera(render)
    else:
        camera = arm_camera(render, trial.log.q[trial.impact.pre_index])
    return save_gif(render_frames(render, trial, camera, samples, frame_size), path)


def render_scene_of(runner, trial) -> RenderScene:
    """The render model of the scene ``trial`` ran on with ``runner``
    (``scenarios.trial.TrialRunner``): an arm's, ``runner.scene``'s robot, tool and wall; a
    standing robot's, its model, the trial's wall and the steps of the trial's stance."""
    if trial.held is not None:
        robot = runner.robot
        stance = robot.description.stances.get(trial.posture)
        return humanoid_render_scene(robot.description, tuple(robot.joint_names), trial.held.wall_x, robot.urdf_path, stance)
    scene = runner.scene
    return arm_render_scene(scene.robot, scene.tool, scene.surface)


def write_trial_video(runner, trial, path: str | Path, frame_size=FRAME_SIZE) -> Path:
    """Render ``trial``, run by ``runner``, on the render model of its scene
    (:func:`render_scene_of`) to the video ``path``."""
    return render_trial_video(render_scene_of(runner, trial), trial, path, frame_size)


def viewer_problem() -> str | None:
    """None when MuJoCo's interactive viewer can open a window, else a one-line explanation: no
    display (DISPLAY and WAYLAND_DISPLAY unset) or its module cannot load."""
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        return "no display to open the viewer in (DISPLAY and WAYLAND_DISPLAY are unset); use --video FILE.gif"
    try:
        import mujoco.viewer  # noqa: F401
    except Exception as error:  # any failure to load the viewer means: no viewer
        return f"the viewer cannot start: {type(error).__name__}: {error}".strip().splitlines()[0]
    return None


def view_trial(runner, trial) -> None:
    """Replay ``trial`` in MuJoCo's interactive viewer (``mujoco.viewer.launch_passive``) on the
    render model of its scene, at the pace of the video's frames (slowed around the contact),
    again and again until the window is closed."""
    import time

    import mujoco.viewer

    render = render_scene_of(runner, trial)
    configurations, samples = configurations_of(trial), shown_samples(trial)
    data = mujoco.MjData(render.model)
    with mujoco.viewer.launch_passive(render.model, data) as viewer:
        while viewer.is_running():
            for k in samples:
                data.qpos[:] = render.qpos(configurations[k])
                mujoco.mj_kinematics(render.model, data)
                viewer.sync()
                time.sleep(1.0 / FRAMES_PER_SECOND)
                if not viewer.is_running():
                    return


def save_gif(frames: list, path: Path) -> Path:
    """Write the frames (PIL images) as a looping GIF at FRAMES_PER_SECOND, atomically."""
    return write_atomic(
        path,
        lambda tmp: frames[0].save(
            tmp, format="GIF", save_all=True, append_images=frames[1:], duration=int(1000 / FRAMES_PER_SECOND), loop=0
        ),
    )
