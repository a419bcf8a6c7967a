"""Kitchen (ITPS) end to end in headless chromium: click the door handle in the camera, the skill plans come and
are drawn, the task's modes are shown, a skill runs; play is bounded to two skills (a whole task takes minutes).

The server takes about 30 s to start (two Kitchen scenes: the warm-up's and the tab's).
Skipped where chromium / chromedriver are missing, unless ``STEER_REQUIRE_BROWSER=1`` (CI).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("fastapi")
pytest.importorskip("selenium")
pytest.importorskip("robosuite")

from ui_pages import assert_no_errors, screenshot, served_page

from steer_envs.ui.browser import Page
from steer_envs.ui.server import UIConfig
from steer_envs.utils.threads import limit_threads

SEED = 0


@pytest.fixture(scope="module")
def page() -> Iterator[Page]:
    yield from served_page(UIConfig(domain="kitchen", seed=SEED, workers=1), 240)


def handle_pixel() -> np.ndarray:
    """Where the microwave's door handle is in the camera image of the seed's scene (the server's is the same)."""
    import gymnasium as gym

    with limit_threads(1, 1):
        env = gym.make("steer_envs/Kitchen-v0", task="microwave", fast_render=True)
    try:
        env.reset(seed=SEED)
        base = env.unwrapped
        return np.asarray(base.world_to_pixel(base.handle_pos)[:2])  # type: ignore[attr-defined]
    finally:
        env.close()


def test_click_the_handle_see_skill_plans_and_run_a_skill(page: Page, tmp_path: Path) -> None:
    declaration = page.state("declaration")
    assert [i["kind"] for i in declaration["interactions"]] == ["point", "nudge"] and declaration["steering"]
    panel = page.panel()
    assert panel["mode"] == "closed_table" and "open_door" in panel["skills legal now"], panel

    page.drag([handle_pixel()])  # Point mode: press and release on the handle
    page.wait("window.steerUI.plansReceived >= 1 || window.steerUI.errors.length > 0", 120, "the skill plans")
    assert_no_errors(page)
    plans = np.asarray(page.state("plans"))
    assert plans.shape == (16, 32, 2) and page.state("drawn")["plans"] == 16
    assert page.plan_pixels_drawn() > 100
    assert "the chosen plan does" in page.panel()
    screenshot(page, "kitchen", tmp_path)

    frames = page.state("frames")
    page.click_button("step")  # the chosen plan runs as one skill
    page.wait(f"window.steerUI.frames > {frames}", 120, "the skill's frame")
    assert len(page.panel()["mode"]) > 0

    frames = page.state("frames")
    page.click_button("play")  # steer with the same click and run, skill after skill: two, then pause
    page.wait(f"window.steerUI.frames >= {frames + 2} || window.steerUI.done", 180, "two played skills")
    page.click_button("play")  # its label reads Pause now
    page.wait("!window.steerUI.playing", 60, "the pause")

    page.click_button("reset")
    page.wait("window.steerUI.panel.some(([k, v]) => k === 'mode' && v === 'closed_table')", 60, "the reset")
    assert page.state("plans") == []
    assert_no_errors(page)
