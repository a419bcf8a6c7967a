"""End to end in a real headless chromium: draw a sketch with the mouse, pick SS, see steered plans drawn.

Skipped where chromium / chromedriver are missing, unless ``STEER_REQUIRE_BROWSER=1``
(CI sets it: ``scripts/bootstrap.sh`` installs both there).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("fastapi")
pytest.importorskip("selenium")

from ui_pages import screenshot, served_page

from steer_envs.core.metrics import sketch_distances
from steer_envs.ui.browser import Page
from steer_envs.ui.server import UIConfig


@pytest.fixture(scope="module")
def page() -> Iterator[Page]:
    yield from served_page(UIConfig(seed=2))


def _plans(page: Page, count: int, sampler: str) -> tuple[np.ndarray, np.ndarray]:
    page.wait(f"window.steerUI.plansReceived >= {count}", 90, f"{sampler} plans")
    last = page.state("history")[-1]
    assert last["sampler"] == sampler and last["batch"] == 32, last
    assert page.state("drawnPlans") == 32
    return np.asarray(page.state("plans")), np.asarray(page.state("interaction"))


def test_sketch_then_ss_beats_rs_on_the_page(page: Page, tmp_path: Path) -> None:
    page.choose("sampler", "RS")
    page.wait("window.steerUI.settings.sampler === 'RS'", 30, "RS chosen")
    agent = np.asarray(page.state("agent"))
    # through free cells from the seed-2 start (32 px a cell): right one, up two, left one, up two
    sketch = agent + np.array([[0.0, 0.0], [32.0, 0.0], [32.0, -64.0], [0.0, -64.0], [0.0, -128.0]])
    page.drag(sketch)
    rs_plans, drawn = _plans(page, 1, "RS")
    assert page.plan_pixels_drawn() > 500
    assert len(drawn) == 64 and np.linalg.norm(drawn[0] - agent) < 3.0  # the mouse path, resampled, came back

    page.choose("sampler", "SS")  # re-steers with the same sketch
    ss_plans, drawn_again = _plans(page, 2, "SS")
    assert np.allclose(drawn, drawn_again)
    assert page.plan_pixels_drawn() > 500
    rs = sketch_distances(rs_plans, drawn).mean()
    ss = sketch_distances(ss_plans, drawn).mean()
    assert ss < 0.8 * rs, f"SS plans {ss:.1f} px from the sketch, RS {rs:.1f} px"
    assert page.state("errors") == []
    assert screenshot(page, "maze2d", tmp_path).stat().st_size > 10_000


def test_nudge_and_step_update_the_view(page: Page) -> None:
    frames = page.state("frames")
    page.set_mode("nudge")
    agent = np.asarray(page.state("agent"))
    page.drag(agent + np.array([[0.0, 0.0], [0.0, -30.0]]))
    page.wait(f"window.steerUI.frames > {frames}", 30, "the nudged frame")
    assert np.linalg.norm(np.asarray(page.state("agent")) - agent) > 5.0
    page.click_button("step")
    page.wait(f"window.steerUI.frames > {frames + 1}", 60, "the stepped frame")
    page.set_mode("sketch")
    assert page.state("errors") == []
