"""ArmScoop (TLI on the Panda arm) end to end in headless chromium: drag the spoon in the camera image, watch
LTL-DS's automaton replan, play until the soup is delivered.

Skipped where chromium / chromedriver are missing, unless ``STEER_REQUIRE_BROWSER=1`` (CI).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("fastapi")
pytest.importorskip("selenium")
pytest.importorskip("robosuite")

from ui_pages import assert_no_errors, screenshot, served_page

from steer_envs.envs.robosuite.arm_scoop import BOWL_X, SOUP_SURFACE, SOUP_Y
from steer_envs.ui.browser import Page
from steer_envs.ui.domains import DOMAINS
from steer_envs.ui.server import UIConfig
from steer_envs.ui.views import PlaneView


@pytest.fixture(scope="module")
def page() -> Iterator[Page]:
    yield from served_page(UIConfig(domain="arm-scoop", seed=0, workers=1), 180)


@pytest.fixture(scope="module")
def view() -> Iterator[PlaneView]:
    """The page's camera (the same scene camera, so the same projection)."""
    domain = DOMAINS["arm-scoop"]
    env = gym.make(domain.env_id, **domain.env_kwargs)
    yield PlaneView(env.unwrapped)
    env.close()


def push_to(page: Page, view: PlaneView, y: float, z: float, change: str) -> dict[str, str]:
    """Drag the spoon to ``(y, z)`` with the mouse; wait until the panel shows mode change ``change``."""
    frames = page.state("frames")
    page.drag([page.state("agent"), view.to_pixels(np.array([BOWL_X, y, z]))])
    page.wait(f"window.steerUI.frames > {frames}", 30, "the pushed frame")
    panel = page.panel()
    assert change in panel["last mode change"], panel
    return panel


def test_push_the_spoon_and_watch_ltl_ds_replan(page: Page, view: PlaneView, tmp_path: Path) -> None:
    declaration = page.state("declaration")
    assert [i["kind"] for i in declaration["interactions"]] == ["push"] and not declaration["steering"]
    assert page.state("drawn")["flow"] == 15 * 15 and page.state("drawn")["attractor"] == 1
    assert page.panel()["automaton mode"] == "a" and page.panel()["plan"] == "a → b → c → d"

    page.click_button("step")
    page.wait("window.steerUI.steps === 20", 30, "a Step of 20 env steps")

    soup = push_to(page, view, SOUP_Y, SOUP_SURFACE - 0.03, "push: a → b")  # into the soup
    assert soup["mode sensors"] == "r on, s off, t off"
    # straight up, the spoon tipped down: it leaves the soup empty, a mode is undone and LTL-DS replans
    push_to(page, view, SOUP_Y, SOUP_SURFACE + 0.12, "push: b → a (undid a mode; replanned: a → b → c → d)")
    assert np.linalg.norm(np.asarray(page.state("agent")) - view.to_pixels([BOWL_X, SOUP_Y, SOUP_SURFACE + 0.12])) < 3
    screenshot(page, "arm-scoop", tmp_path)

    page.click_button("play")  # LTL-DS scoops again and delivers the soup
    page.wait("window.steerUI.done && !window.steerUI.playing", 90, "the episode's end")
    panel = page.panel()
    assert panel["automaton mode"] == "d" and "success" in page.driver.find_element("id", "s-episode").text, panel

    page.click_button("reset")
    page.wait("!window.steerUI.done && window.steerUI.steps === 0", 30, "the reset")
    assert page.panel()["automaton mode"] == "a"
    assert_no_errors(page)
