"""BlockStack end to end in headless chromium: click a cube in Point mode, the skill plans come and are drawn.

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

from ui_pages import screenshot, served_page

from steer_envs.ui import Session
from steer_envs.ui.browser import Page
from steer_envs.ui.server import UIConfig
from steer_envs.utils.threads import limit_threads

SEED = 0


@pytest.fixture(scope="module")
def page() -> Iterator[Page]:
    yield from served_page(UIConfig(domain="blockstack", seed=SEED, workers=1), 180)


def cube_pixel(cube: int) -> np.ndarray:
    """Where cube ``cube`` of the seed's scene is in the camera image (the server's session has the same scene)."""
    with limit_threads(1, 1):
        session = Session("blockstack", seed=SEED)
    try:
        return np.asarray(session.pixels.to_pixels(session.env.unwrapped.cube_pos[cube]))  # type: ignore[attr-defined]
    finally:
        session.close()


def test_a_click_on_a_cube_brings_skill_plans_drawn_in_the_camera(page: Page, tmp_path: Path) -> None:
    page.set_mode("point")
    page.drag([cube_pixel(0)])  # press and release on the cube: a click
    page.wait("window.steerUI.plansReceived >= 1 || window.steerUI.errors.length > 0", 180, "the skill plans")
    assert page.state("errors") == []
    plans = np.asarray(page.state("plans"))
    assert plans.ndim == 3 and plans.shape[-1] == 2 and len(plans) == page.state("drawnPlans")
    assert page.plan_pixels_drawn() > 100
    screenshot(page, "blockstack", tmp_path)
