"""The steer-ui page in headless chromium for a browser test: served, opened, ready; skipped without chromium.

Skipped where chromium / chromedriver are missing, unless ``STEER_REQUIRE_BROWSER=1``
(CI sets it: ``scripts/bootstrap.sh`` installs both there).
"""

from __future__ import annotations

import os
from collections.abc import Iterator

import pytest

from steer_envs.ui.browser import BrowserUnavailable, Page, RunningServer, chromium_paths, open_page
from steer_envs.ui.server import UIConfig
from steer_envs.utils.threads import limit_threads


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
