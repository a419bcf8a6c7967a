"""Lift (GLiDE on a robosuite arm) end to end in headless chromium: the learned mode beside the true one along the
run, a drag of the gripper (a push), a push the arm refuses shown as a notice, play to the end, reset.

The classifier and the BC networks are trained when the server starts (the quick setup, in a temporary cache:
about half a minute on one core; the UI's default setup about 3 minutes the first time, then is cached).
Skipped where chromium / chromedriver are missing, unless ``STEER_REQUIRE_BROWSER=1`` (CI).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("fastapi")
pytest.importorskip("selenium")
pytest.importorskip("torch")
pytest.importorskip("robosuite")

from ui_pages import assert_no_errors, screenshot, served_page

from steer_envs.ui.arm_glide import quick_arm_glide_setup
from steer_envs.ui.browser import Page
from steer_envs.ui.server import UIConfig


@pytest.fixture(scope="module")
def page(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Page]:
    options = {"setup": quick_arm_glide_setup(), "cache_dir": str(tmp_path_factory.mktemp("glide-arm"))}
    yield from served_page(UIConfig(domain="lift-glide", seed=0, workers=1, controller_options=options), 240)


def test_learned_modes_beside_the_true_ones_a_push_and_a_refused_one(page: Page, tmp_path: Path) -> None:
    declaration = page.state("declaration")
    assert [i["kind"] for i in declaration["interactions"]] == ["push"] and not declaration["steering"]
    assert page.state("drawn")["modes"] == 2 and page.state("drawn")["target"] == 1
    panel = page.panel()
    assert panel["true mode"] == "reach" and panel["learned mode"] in ("reach", "lift", "reach_height"), panel

    page.click_button("step")
    page.wait("window.steerUI.steps === 10 && window.steerUI.drawn.trail === 1", 30, "a Step and the path")
    assert page.panel()["agreement along the run"].endswith("of 11 steps")

    agent = np.asarray(page.state("agent"))  # drag the gripper up on the screen: it rises in the drag plane
    up = agent + np.array([0.0, -25.0])
    frames = page.state("frames")
    page.drag([agent, up])
    page.wait(f"window.steerUI.frames > {frames}", 30, "the pushed frame")
    assert np.linalg.norm(np.asarray(page.state("agent")) - up) < 3.0
    assert page.state("notices") == []

    frames = page.state("frames")  # under the table: the arm refuses, the page says so, nothing moves
    moved = np.asarray(page.state("agent"))
    page.drag([moved, [moved[0], page.state("height") - 2.0]])
    page.wait(f"window.steerUI.frames > {frames}", 30, "the refused push's frame")
    assert "push refused" in page.state("notices")[-1] and "`to`" in page.state("notices")[-1]
    assert np.linalg.norm(np.asarray(page.state("agent")) - moved) < 1e-6

    page.click_button("play")
    page.wait("window.steerUI.done && !window.steerUI.playing", 90, "the episode's end")
    assert page.panel()["true along the run"] != "–" and page.state("drawn")["modes"] == 2
    screenshot(page, "lift-glide", tmp_path)

    page.click_button("reset")
    page.wait("!window.steerUI.done && window.steerUI.steps === 0", 30, "the reset")
    assert page.panel()["agreement along the run"].endswith("of 1 steps")
    assert_no_errors(page)
