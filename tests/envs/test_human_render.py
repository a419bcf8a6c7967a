"""``render_mode="human"`` of the 2D envs: a pygame window showing the ``rgb_array`` frames, under Xvfb.

The window tests start a private Xvfb display; they are skipped where Xvfb or
pygame is missing, unless ``STEER_REQUIRE_BROWSER=1`` (CI sets it:
``scripts/bootstrap.sh`` installs both there), then they fail.
"""

from __future__ import annotations

import os
import select
import shutil
import subprocess
import sys
from collections.abc import Iterator
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.error import DependencyNotInstalled

import steer_envs
from steer_envs.envs.human_view import INSTALL_HINT, HumanView

#: every 2D env: the kinematic domains and the Maze2D mazes (one goal-conditioned variant too)
IDS_2D = [
    *steer_envs.env_ids(kinematic_only=True),
    *(i for i in steer_envs.env_ids() if "Maze2D" in i),
    "steer_envs/Maze2D-UmazeGoal-v0",
]
ARM_IDS = [i for i in steer_envs.env_ids() if i not in IDS_2D]


def _unavailable(reason: str) -> None:
    """Skip, or fail where CI asks for the display tests (``STEER_REQUIRE_BROWSER=1``)."""
    if os.environ.get("STEER_REQUIRE_BROWSER") == "1":
        pytest.fail(f"{reason} (STEER_REQUIRE_BROWSER=1)")
    pytest.skip(reason)


@pytest.fixture(scope="module")
def xvfb_display() -> Iterator[str]:
    """A private Xvfb display (24-bit, so pixels read back exactly), e.g. ``":7"``."""
    try:
        import pygame  # noqa: F401
    except ImportError:
        _unavailable(f"pygame is not installed ({INSTALL_HINT})")
    xvfb = shutil.which("Xvfb")
    if xvfb is None:
        _unavailable("Xvfb is not installed (apt-get install xvfb)")
    assert xvfb is not None
    read_fd, write_fd = os.pipe()
    proc = subprocess.Popen(
        [xvfb, "-displayfd", str(write_fd), "-screen", "0", "1024x768x24", "-nolisten", "tcp"],
        pass_fds=(write_fd,),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    os.close(write_fd)
    try:
        ready, _, _ = select.select([read_fd], [], [], 30.0)
        number = os.read(read_fd, 64).decode().strip() if ready else ""
        if not number:
            pytest.fail("Xvfb did not report a display number within 30 s")
        yield f":{number}"
    finally:
        os.close(read_fd)
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


@pytest.fixture
def display(xvfb_display: str, monkeypatch: pytest.MonkeyPatch) -> str:
    """SDL draws on the private display."""
    monkeypatch.setenv("DISPLAY", xvfb_display)
    monkeypatch.setenv("SDL_VIDEODRIVER", "x11")
    return xvfb_display


def _window_pixels() -> np.ndarray:
    """The pygame window's pixels as an ``(H, W, 3)`` image."""
    import pygame

    surface = pygame.display.get_surface()
    assert surface is not None, "no pygame window is open"
    return np.transpose(pygame.surfarray.array3d(surface), (1, 0, 2))


def _frame(env: gym.Env[Any, Any]) -> np.ndarray:
    """The ``rgb_array`` frame of ``env``."""
    frame = env.render()
    assert isinstance(frame, np.ndarray)
    return frame


@pytest.mark.parametrize("env_id", IDS_2D)
def test_human_window_shows_the_rgb_array_frames(env_id: str, display: str) -> None:
    import pygame

    human = gym.make(env_id, render_mode="human")
    twin = gym.make(env_id, render_mode="rgb_array")
    assert "human" in human.metadata["render_modes"] and human.metadata["render_fps"] > 0
    try:
        human.reset(seed=3)
        twin.reset(seed=3)
        np.testing.assert_array_equal(_window_pixels(), _frame(twin))  # reset shows the first frame
        actions = human.action_space
        actions.seed(0)
        for _ in range(3):
            action = actions.sample()
            human.step(action)
            twin.step(action)
            np.testing.assert_array_equal(_window_pixels(), _frame(twin))
        assert human.render() is None  # "human" shows, returns nothing (Gymnasium's convention)
        np.testing.assert_array_equal(_window_pixels(), _frame(twin))
        assert pygame.display.get_init()
    finally:
        human.close()
        twin.close()
    assert not pygame.display.get_init()  # close() quits pygame


@pytest.mark.parametrize("env_id", ["steer_envs/SoupScoop-v0", "steer_envs/Maze2D-Umaze-v0"])
def test_without_pygame_human_mode_names_the_extra(env_id: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "pygame", None)  # import pygame -> ImportError
    with pytest.raises(DependencyNotInstalled, match=r'pip install "steer-envs\[human\]"'):
        gym.make(env_id, render_mode="human")
    env = gym.make(env_id, render_mode="rgb_array")  # the other modes need no pygame
    env.reset(seed=0)
    assert env.render() is not None
    env.close()


@pytest.mark.filterwarnings("ignore:.*not in the possible render_modes")  # Gymnasium's warning before the error
@pytest.mark.parametrize("env_id", ["steer_envs/Cooking-v0", "steer_envs/Maze2D-Medium-v0"])
@pytest.mark.parametrize("mode", ["Human", "humans", "rgb"])
def test_unknown_render_modes_are_a_value_error_naming_render_mode(env_id: str, mode: str) -> None:
    with pytest.raises(ValueError, match="render_mode"):
        gym.make(env_id, render_mode=mode)


def test_render_modes_advertised() -> None:
    """The 2D envs list "human"; the arm envs stay rgb_array-only (checked on their classes, no simulator)."""
    for env_id in IDS_2D:
        env = gym.make(env_id)
        assert env.metadata["render_modes"] == ["rgb_array", "human"], env_id
        env.close()
    for env_id in ARM_IDS:
        spec = gym.spec(env_id)
        assert isinstance(spec.entry_point, str)
        module, name = spec.entry_point.split(":")
        cls: Any = getattr(__import__(module, fromlist=[name]), name)
        assert cls.metadata["render_modes"] == ["rgb_array"], env_id


def test_human_view_refuses_frames_that_are_not_rgb_images() -> None:
    pytest.importorskip("pygame")
    view = HumanView(fps=30)
    for bad in (np.zeros((4, 4), np.uint8), np.zeros((4, 4, 4), np.uint8), np.zeros((4, 4, 3), np.float32)):
        with pytest.raises(ValueError, match="frame"):
            view.show(bad)
    assert not view.is_open
    view.close()  # a no-op: no window was opened
    with pytest.raises(ValueError, match="fps"):
        HumanView(fps=0)
