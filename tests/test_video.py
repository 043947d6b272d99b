"""The video of a trial (``scenarios.video``): the robot's meshes fill the picture and move, the
overlay states the time, the contact speed and the binding joint's limit and prediction, the
contact is slowed down, and a format other than GIF is refused."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from PIL import Image

from impactqp.controller.model.choice import DEFAULT_CHOICE
from impactqp.controller.model.postures import DEFAULT_WALL
from impactqp.controller.model.validation import BadInputError
from impactqp.scenarios import video
from impactqp.scenarios.trial import TrialRunner
from impactqp.sim.render_scene import arm_render_scene
from impactqp.sim.runner import TrialSpec

SIZE = (120, 160)  # small frames: the tests render few


@pytest.fixture(scope="module")
def trial():
    """The Panda with the impact tip at elbow_up, 0.1 m/s from rest (``impactqp simulate``'s trial)."""
    posture = DEFAULT_CHOICE.posture("elbow_up")
    runner = TrialRunner.build(DEFAULT_WALL, None, DEFAULT_CHOICE)
    result = runner.run(TrialSpec(posture.name, posture.q, 0.1, jump_model="crb", start_at_rest=True, start_distance=0.05))
    return runner, result


@pytest.fixture(scope="module")
def render(trial):
    scene = trial[0].scene
    return arm_render_scene(scene.robot, scene.tool, scene.surface)


def picture(frame) -> np.ndarray:
    """A frame's pixels below its overlay band, as floats."""
    return np.asarray(frame.convert("RGB"), dtype=float)[SIZE[0] // 4:]


def test_an_offscreen_renderer_exists_here():
    assert video.offscreen_backend_problem() is None


@given(st.floats(0.2, 0.8))
def test_the_contact_is_slowed_down_and_the_rest_runs_at_real_time(t_contact):
    t = np.arange(0.0, 1.0, 1e-3)
    shown = t[video.frame_samples(t, t_contact, video.ARM_AFTER)]
    steps = np.diff(shown)
    slow, real = 1.0 / (video.FRAMES_PER_SECOND * video.SLOW_MOTION), 1.0 / video.FRAMES_PER_SECOND
    window_start = t_contact - video.SPAN
    near = np.abs(shown[:-1] - t_contact) < video.SPAN - 2e-3
    entering = (shown[:-1] < window_start) & (shown[:-1] + real > window_start - 2e-3)
    far = (np.abs(shown[:-1] - t_contact) > video.SPAN + 2e-3) & ~entering
    assert near.any() and far.any()
    np.testing.assert_allclose(steps[near], slow, atol=1.01e-3)
    np.testing.assert_allclose(steps[far], real, atol=1.01e-3)
    assert np.abs(shown - window_start).min() < 1.01e-3  # the slow motion starts at the window's start (one sample)
    assert (steps[entering] <= real + 1.01e-3).all()
    assert shown[0] == pytest.approx(max(t_contact - video.BEFORE, 0.0), abs=1e-3)
    assert shown[-1] <= t_contact + video.ARM_AFTER


def test_the_meshes_cover_the_picture_and_move(trial, render):
    """The robot's meshes cover 7 % of the frame and more (about 10 %; the capsules between body
    origins of the former stick figure covered under 5 % from this camera) and the frames
    change where the arm moves."""
    runner, result = trial
    camera = video.arm_camera(render, result.log.q[result.impact.pre_index])
    first, contact = video.shown_samples(result)[0], result.impact.pre_index
    frames = video.render_frames(render, result, camera, [first, contact], SIZE)
    hidden = render.model.geom_rgba.copy()
    meshes = render.model.geom_type == video.mujoco.mjtGeom.mjGEOM_MESH
    render.model.geom_rgba[meshes, 3] = 0.0
    try:
        bare = video.render_frames(render, result, camera, [contact], SIZE)[0]
    finally:
        render.model.geom_rgba[:] = hidden
    robot = np.abs(picture(frames[1]) - picture(bare)).sum(axis=2) > 30
    assert robot.mean() > 0.07
    moved = np.abs(picture(frames[1]) - picture(frames[0])).sum(axis=2) > 30
    assert moved.mean() > 0.002


def test_the_overlay_states_time_speed_limit_and_prediction(trial, render):
    runner, result = trial
    k = result.impact.pre_index
    lines = video.overlay_lines(result, render.robot, k)
    j = video.binding_joint(result, render.robot.dq_max)
    post = result.impact.dq_pre + result.predicted["crb"]  # eq. (19)
    assert j == int(np.argmax(np.abs(post) / render.robot.dq_max))
    t_ms = (result.log.t[k] - result.impact.t_contact_start) * 1e3
    assert f"{t_ms:+7.1f} ms" in lines[0] and "slow motion" in lines[0]
    assert f"{result.contact_speed:.3f} m/s" in lines[1]
    assert render.robot.joints[j] in lines[2]
    assert f"limit {render.robot.dq_max[j]:.3f}" in lines[2] and f"dq+ {post[j]:+.3f}" in lines[2]
    assert f"|dq| {abs(result.log.dq[k, j]):.3f}" in lines[2]
    blank = Image.new("RGB", (SIZE[1], SIZE[0]), (128, 128, 128))
    band = np.asarray(video.draw_overlay(blank, lines))[: SIZE[0] // 4]
    assert (band.sum(axis=2) > 600).mean() > 0.02  # white text on the band
    assert (band.sum(axis=2) < 100).mean() > 0.3  # the dark band


def test_a_video_is_a_gif_and_another_suffix_is_refused(trial, render, tmp_path):
    runner, result = trial
    with pytest.raises(BadInputError, match="GIF"):
        video.render_trial_video(render, result, tmp_path / "impact.mp4", SIZE)
    assert not (tmp_path / "impact.mp4").exists()
    path = video.render_trial_video(render, result, tmp_path / "impact.GIF", SIZE)
    with Image.open(path) as image:
        assert image.format == "GIF" and image.n_frames == len(video.shown_samples(result))


def test_the_viewer_needs_a_display(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert "no display" in video.viewer_problem()
