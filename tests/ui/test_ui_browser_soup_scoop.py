"""SoupScoop (TLI) end to end in headless chromium: drag the spoon, watch LTL-DS's automaton replan, play to the end,
save the session and export its video.

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

from ui_pages import assert_no_errors, screenshot, served_page

from steer_envs.ui.browser import Page
from steer_envs.ui.server import UIConfig
from steer_envs.ui.views import PixelMap


@pytest.fixture(scope="module")
def page() -> Iterator[Page]:
    yield from served_page(UIConfig(domain="soup-scoop", seed=1, workers=1))


def push_to(page: Page, world: tuple[float, float], change: str) -> dict[str, str]:
    """Drag the agent to ``world`` with the mouse; wait until the panel shows mode change ``change``."""
    env = gym.make("steer_envs/SoupScoop-v0")
    model = env.unwrapped.model  # type: ignore[attr-defined]
    view = PixelMap.from_box(model.low, model.high, page.state("width"), page.state("height"))
    env.close()
    frames = page.state("frames")
    page.drag([page.state("agent"), view.to_pixels(np.asarray(world))])
    page.wait(f"window.steerUI.frames > {frames}", 30, "the pushed frame")
    panel = page.panel()
    assert change in panel["last mode change"], panel
    return panel


def test_push_the_spoon_and_watch_ltl_ds_replan(page: Page, tmp_path: Path) -> None:
    declaration = page.state("declaration")
    assert [i["kind"] for i in declaration["interactions"]] == ["push"] and not declaration["steering"]
    assert page.driver.execute_script("return document.getElementById('sampler-box').hidden") is True
    assert page.state("drawn")["flow"] == 15 * 15 and page.state("drawn")["attractor"] == 1
    assert page.panel()["automaton mode"] == "a" and page.panel()["plan"] == "a → b → c → d"

    page.click_button("step")
    page.wait("window.steerUI.steps === 20", 30, "a Step of 20 env steps")

    push_to(page, (-2.0, -6.0), "push: a → b")  # into the soup
    push_to(page, (4.0, -2.0), "push: b → c")  # up into the pink lane: soup on the spoon
    undone = push_to(page, (-4.0, 2.0), "push: c → a (undid a mode; replanned: a → b → c → d)")  # spilled
    assert undone["automaton mode"] == "a" and undone["mode sensors"] == "r off, s off, t off"
    screenshot(page, "soup-scoop", tmp_path)

    page.click_button("play")  # LTL-DS recovers and delivers the soup
    page.wait("window.steerUI.done && !window.steerUI.playing", 60, "the episode's end")
    panel = page.panel()
    assert panel["automaton mode"] == "d" and int(panel["steps"]) <= 1000, panel

    page.click_button("save")  # the session as a download: every push and step, replayable
    page.wait("window.steerUI.downloads.length === 1", 30, "the saved session")
    saved = page.state("downloads")[0]
    assert saved["name"].startswith("steer-ui-soup-scoop-seed1-") and saved["mime"] == "application/json"
    page.click_button("export")  # replayed in a fresh session, every frame as recorded, encoded as an MP4
    page.wait("window.steerUI.downloads.length === 2", 120, "the exported video")
    video = page.state("downloads")[1]
    assert video["name"] == "steer-ui-soup-scoop-seed1.mp4" and video["size"] > 10_000 and video["identical"] is True

    page.click_button("reset")
    page.wait("!window.steerUI.done && window.steerUI.steps === 0", 30, "the reset")
    assert page.panel()["automaton mode"] == "a"
    assert_no_errors(page)
