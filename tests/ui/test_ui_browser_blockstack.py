"""BlockStack end to end in headless chromium: click a cube in Point mode, the skill plans come and are drawn.

Skipped where chromium / chromedriver are missing, unless ``STEER_REQUIRE_BROWSER=1`` (CI).
"""

from __future__ import annotations

import os
from collections.abc import Iterator

import numpy as np
import pytest

pytest.importorskip("fastapi")
pytest.importorskip("selenium")
pytest.importorskip("robosuite")

from steer_envs.ui import Session
from steer_envs.ui.browser import BrowserUnavailable, Page, RunningServer, chromium_paths, open_page
from steer_envs.ui.server import UIConfig
from steer_envs.utils.threads import limit_threads

SEED = 0


@pytest.fixture(scope="module")
def page() -> Iterator[Page]:
    try:
        chromium_paths()
    except BrowserUnavailable as exc:
        if os.environ.get("STEER_REQUIRE_BROWSER") == "1":
            pytest.fail(str(exc))
        pytest.skip(str(exc))
    with limit_threads(1, 1), RunningServer(UIConfig(domain="blockstack", seed=SEED, workers=1)) as server:
        browser = open_page(server.url)
        try:
            browser.wait_ready(180)
            yield browser
        finally:
            browser.close()


def cube_pixel(cube: int) -> np.ndarray:
    """Where cube ``cube`` of the seed's scene is in the camera image (the server's session has the same scene)."""
    with limit_threads(1, 1):
        session = Session("blockstack", seed=SEED)
    try:
        return np.asarray(session.pixels.to_pixels(session.env.unwrapped.cube_pos[cube]))  # type: ignore[attr-defined]
    finally:
        session.close()


def test_a_click_on_a_cube_brings_skill_plans_drawn_in_the_camera(page: Page) -> None:
    page.set_mode("point")
    page.drag([cube_pixel(0)])  # press and release on the cube: a click
    page.wait("window.steerUI.plansReceived >= 1 || window.steerUI.errors.length > 0", 180, "the skill plans")
    assert page.state("errors") == []
    plans = np.asarray(page.state("plans"))
    assert plans.ndim == 3 and plans.shape[-1] == 2 and len(plans) == page.state("drawnPlans")
    assert page.plan_pixels_drawn() > 100
