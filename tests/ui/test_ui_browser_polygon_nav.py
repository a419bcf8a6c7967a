"""PolygonNav (GLiDE) end to end in headless chromium: the learned mode map over the image, drag the agent away,
GLiDE+Planning replans and reaches the goal.

The mode classifier is trained when the server starts (the quick setup: about 15 s on one core, in a
temporary cache; the UI's default, the suites' setup, takes minutes the first time).
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
pytest.importorskip("torch")

from ui_pages import assert_no_errors, screenshot, served_page

from steer_envs.ui.browser import Page
from steer_envs.ui.controllers import quick_glide_setup
from steer_envs.ui.server import UIConfig
from steer_envs.ui.views import PixelMap

ENV = "steer_envs/PolygonNav-3Mode-v0"


@pytest.fixture(scope="module")
def page(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Page]:
    cache = tmp_path_factory.mktemp("glide")
    options = {"setup": quick_glide_setup(), "cache_dir": str(cache)}
    yield from served_page(UIConfig(domain="polygon-nav", seed=0, workers=1, controller_options=options), 180)


def pixel_of(page: Page, world: tuple[float, float]) -> np.ndarray:
    """Where world point ``world`` is in the page's image; it must lie in free space."""
    env = gym.make(ENV)
    model = env.unwrapped.model  # type: ignore[attr-defined]
    view = PixelMap.from_box(model.low, model.high, page.state("width"), page.state("height"))
    assert model.mode_of(np.asarray([world]))[0] == 0, f"{world} is not in free space"
    env.close()
    return view.to_pixels(np.asarray(world))


def test_the_learned_modes_a_push_and_glide_planning_recovering(page: Page, tmp_path: Path) -> None:
    declaration = page.state("declaration")
    assert [i["kind"] for i in declaration["interactions"]] == ["push"] and not declaration["steering"]
    page.wait("window.steerUI.drawn.mode_map === 1", 30, "the learned mode map")
    panel = page.panel()
    assert panel["learned mode"] == panel["true mode"] == "free", panel

    page.click_button("step")
    page.wait("window.steerUI.steps === 5 && window.steerUI.drawn.plan === 1", 30, "a Step and the planned path")
    planned = int(page.panel()["paths planned (mode changes, pushes)"])

    corner = pixel_of(page, (7.0, -7.0))  # the far free corner: GLiDE+Planning must go round both polygons
    frames = page.state("frames")
    page.drag([page.state("agent"), corner])
    page.wait(f"window.steerUI.frames > {frames}", 30, "the pushed frame")
    assert np.linalg.norm(np.asarray(page.state("agent")) - corner) < 3.0
    page.click_button("step")  # the jump is seen: GLiDE+Planning plans a new path from there
    page.wait("window.steerUI.steps === 10", 30, "the Step after the push")
    assert int(page.panel()["paths planned (mode changes, pushes)"]) > planned
    screenshot(page, "polygon-nav", tmp_path)

    page.click_button("play")
    page.wait("window.steerUI.done && !window.steerUI.playing", 60, "the episode's end")
    assert "success" in page.driver.find_element("id", "s-episode").text

    page.click_button("reset")
    page.wait("!window.steerUI.done && window.steerUI.steps === 0", 30, "the reset")
    assert page.state("drawn")["mode_map"] == 1
    assert_no_errors(page)
