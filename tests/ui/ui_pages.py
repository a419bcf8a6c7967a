"""The steer-ui page in headless chromium for a browser test: served, opened, ready; skipped without chromium.

Skipped where chromium / chromedriver are missing, unless ``STEER_REQUIRE_BROWSER=1``
(CI sets it: ``scripts/bootstrap.sh`` installs both there).
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest

from steer_envs.ui.browser import BrowserUnavailable, Page, RunningServer, chromium_paths, open_page
from steer_envs.ui.server import UIConfig
from steer_envs.utils.threads import limit_threads


def screenshot(page: Page, domain: str, tmp_path: Path) -> Path:
    """Save ``ui-<domain>.png`` (small: 256 colours) in ``$STEER_UI_SCREENSHOT_DIR`` (e.g. docs/img) or ``tmp_path``."""
    return page.screenshot(Path(os.environ.get("STEER_UI_SCREENSHOT_DIR", tmp_path)) / f"ui-{domain}.png", colors=256)


def assert_no_errors(page: Page) -> None:
    """Nothing went wrong on the page: no error shown or thrown, none in the browser's console."""
    assert page.state("errors") == [], page.state("errors")
    assert page.console_errors() == []


def served_page(config: UIConfig, ready_timeout: float = 60.0) -> Iterator[Page]:
    """Serve ``config`` on a free port and yield the page once it says ready (a fixture body)."""
    try:
        chromium_paths()
    except BrowserUnavailable as exc:
        if os.environ.get("STEER_REQUIRE_BROWSER") == "1":
            pytest.fail(str(exc))
        pytest.skip(str(exc))
    with limit_threads(1, 1), RunningServer(config) as server:
        browser = open_page(server.url)
        try:
            browser.wait_ready(ready_timeout)
            yield browser
        finally:
            browser.close()
