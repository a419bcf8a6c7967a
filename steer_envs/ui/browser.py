"""Run steer-ui in-process and drive its page in a headless chromium (tests, benchmark, README screenshot).

:class:`RunningServer` serves the app on 127.0.0.1 in a background thread;
:func:`open_page` starts Debian's ``chromium`` through ``chromedriver``
(selenium) and :class:`Page` draws sketches with real mouse events and reads
``window.steerUI`` back.
"""

from __future__ import annotations

import os
import shutil
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.core.extras import install_command
from steer_envs.core.validation import BoundExceeded, real_scalar
from steer_envs.ui.server import UIConfig, create_app

__all__ = ["BrowserUnavailable", "Page", "RunningServer", "chromium_paths", "open_page"]

#: seconds the server may take to load the policy and bind
START_TIMEOUT_S = 120.0


class BrowserUnavailable(RuntimeError):
    """No chromium / chromedriver on this machine (``scripts/bootstrap.sh`` installs them)."""


class RunningServer:
    """steer-ui on ``127.0.0.1:<free port>`` in a daemon thread; use as a context manager.

    ``start_timeout``: seconds it may take to load and warm up before it listens (a domain that trains its
    setup on first use, e.g. ``lift-glide`` without a cache, takes minutes).
    """

    def __init__(self, config: UIConfig | None = None, port: int = 0, start_timeout: float = START_TIMEOUT_S) -> None:
        import uvicorn

        self.app = create_app(config)
        self.server = uvicorn.Server(uvicorn.Config(self.app, host="127.0.0.1", port=port, log_level="warning"))
        self.thread = threading.Thread(target=self.server.run, name="steer-ui-server", daemon=True)
        self.port = port
        self.start_timeout = real_scalar(start_timeout, "start_timeout", low=0.0, owner="RunningServer")

    @property
    def url(self) -> str:
        """The page's address."""
        return f"http://127.0.0.1:{self.port}"

    @property
    def ws_url(self) -> str:
        """The WebSocket's address."""
        return f"ws://127.0.0.1:{self.port}/ws"

    def start(self) -> RunningServer:
        """Start and wait until it listens (``BoundExceeded`` after ``start_timeout`` seconds)."""
        self.thread.start()
        deadline = time.monotonic() + self.start_timeout
        while not self.server.started:
            if not self.thread.is_alive():
                raise RuntimeError("steer-ui server thread exited while starting (see the log above)")
            if time.monotonic() > deadline:
                raise BoundExceeded(f"steer-ui did not start within {self.start_timeout:.0f} s")
            time.sleep(0.05)
        sockets = [s for server in self.server.servers for s in server.sockets]
        self.port = int(sockets[0].getsockname()[1])
        return self

    def stop(self) -> None:
        """Ask the server to exit and wait for its thread (10 s at most)."""
        self.server.should_exit = True
        self.thread.join(timeout=10.0)

    def __enter__(self) -> RunningServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


def chromium_paths() -> tuple[str, str]:
    """``(chromium, chromedriver)`` executables; ``BrowserUnavailable`` when either is missing."""
    browser = os.environ.get("STEER_UI_CHROMIUM") or shutil.which("chromium") or shutil.which("chromium-browser")
    driver = os.environ.get("STEER_UI_CHROMEDRIVER") or shutil.which("chromedriver")
    if not browser or not driver:
        raise BrowserUnavailable(
            "chromium and chromedriver are needed (apt-get install chromium chromium-driver; scripts/bootstrap.sh does)"
        )
    return browser, driver


class Page:
    """The steer-ui page in a browser: draw, click, choose, read the state the page exposes."""

    def __init__(self, driver: Any) -> None:
        self.driver = driver

    def state(self, key: str) -> Any:
        """``window.steerUI[key]``."""
        return self.driver.execute_script(f"return window.steerUI ? window.steerUI[{key!r}] : null;")

    def wait(self, condition: str, timeout: float = 30.0, what: str = "the page") -> Any:
        """Poll the JS expression ``condition`` until truthy; ``BoundExceeded`` after ``timeout`` s."""
        deadline = time.monotonic() + timeout
        while True:
            value = self.driver.execute_script(f"return ({condition});")
            if value:
                return value
            if time.monotonic() > deadline:
                errors = self.state("errors")
                raise BoundExceeded(f"{what}: `{condition}` not true within {timeout:.0f} s (page errors: {errors})")
            time.sleep(0.05)

    def wait_ready(self, timeout: float = 60.0) -> None:
        """Wait for the server's ``ready`` message."""
        self.wait("window.steerUI && window.steerUI.ready", timeout, "ready")

    def choose(self, element_id: str, value: str) -> None:
        """Pick ``value`` in the ``<select id=element_id>`` and fire ``change`` as a user's pick does.

        (Selenium's ``Select`` leaves headless chromium's drop-down open, swallowing the next mouse press.)
        """
        found = self.driver.execute_script(
            "const el = document.getElementById(arguments[0]);"
            "if (!el || ![...el.options].some((o) => o.value === arguments[1] && !o.disabled)) return false;"
            "el.value = arguments[1]; el.dispatchEvent(new Event('change')); return true;",
            element_id,
            value,
        )
        if not found:
            raise ValueError(f"the page has no enabled option {value!r} in #{element_id}")

    def set_mode(self, mode: str) -> None:
        """Click the input-mode radio button (``sketch``, ``point``, ``nudge``)."""
        from selenium.webdriver.common.by import By

        self.driver.find_element(By.CSS_SELECTOR, f"input[name=mode][value={mode}]").click()

    def drag(self, pixels: Sequence[Sequence[float]]) -> None:
        """Press at the first image pixel, move through the rest, release: real mouse events on the canvas."""
        from selenium.webdriver.common.action_chains import ActionChains
        from selenium.webdriver.common.by import By

        canvas = self.driver.find_element(By.ID, "overlay")
        self.driver.execute_script("arguments[0].scrollIntoView({block: 'nearest'});", canvas)
        scale = self.state("scale")
        # ActionChains offsets are from the element's in-view centre: the middle of its part inside the viewport
        left, top, right, bottom, view_w, view_h = self.driver.execute_script(
            "const r = arguments[0].getBoundingClientRect();"
            "return [r.left, r.top, r.right, r.bottom, window.innerWidth, window.innerHeight];",
            canvas,
        )
        lo = np.array([max(left, 0.0), max(top, 0.0)])
        hi = np.array([min(right, view_w), min(bottom, view_h)])
        centre = (lo + hi) / 2.0
        pts = np.asarray(pixels, dtype=np.float64)
        css = np.array([left, top]) + pts * scale
        if np.any(css < lo) or np.any(css > hi):
            raise ValueError(f"Page.drag: image pixels {pixels!r} are outside the visible canvas (enlarge the window)")
        offsets = np.rint(np.clip(css, lo + 1, hi - 1) - centre).astype(int)
        chain = ActionChains(self.driver, duration=10)
        chain.move_to_element_with_offset(canvas, int(offsets[0][0]), int(offsets[0][1])).click_and_hold()
        previous = offsets[0]
        for offset in offsets[1:]:
            chain.move_by_offset(int(offset[0] - previous[0]), int(offset[1] - previous[1]))
            previous = offset
        chain.release().perform()

    def click_button(self, element_id: str) -> None:
        """Click a button by id."""
        from selenium.webdriver.common.by import By

        self.driver.find_element(By.ID, element_id).click()

    def panel(self) -> dict[str, str]:
        """The domain's panel rows shown beside the view, label -> value."""
        return {str(label): str(value) for label, value in self.state("panel") or []}

    def console_errors(self) -> list[str]:
        """Errors the browser's console logged since the last call (uncaught exceptions, failed loads)."""
        try:
            entries = self.driver.get_log("browser")
        except Exception:  # a driver without log access: nothing to read
            return []
        return [str(e.get("message", "")) for e in entries if e.get("level") == "SEVERE"]

    def plan_pixels_drawn(self) -> int:
        """Opaque overlay pixels in the plan colours (teal, orange, dark blue): the plans really are on the canvas."""
        script = """
            const c = document.getElementById('overlay');
            const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
            let n = 0;
            for (let i = 0; i < d.length; i += 4) {
              if (d[i + 3] < 100) continue;
              const r = d[i], g = d[i + 1], b = d[i + 2];
              const teal = g > 120 && r < 90 && b > 110, orange = r > 200 && g > 110 && g < 170 && b < 90;
              if (teal || orange || (b > 110 && r < 60 && g < 80)) n++;
            }
            return n;"""
        return int(self.driver.execute_script(script))

    def screenshot(self, path: str | os.PathLike[str], colors: int | None = None) -> Path:
        """Save a PNG of the window (atomically); ``colors``: reduce to that many (a small file for the docs)."""
        from steer_envs.io import atomic_write_bytes

        out = Path(path)
        png = self.driver.get_screenshot_as_png()
        if colors is not None:
            import io

            from PIL import Image

            # octree keeps the small, saturated overlay colours (median cut merges them into the greys)
            rgb = Image.open(io.BytesIO(png)).convert("RGB")
            image = rgb.quantize(colors=colors, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE)
            buffer = io.BytesIO()
            image.save(buffer, format="PNG", optimize=True)
            png = buffer.getvalue()
        atomic_write_bytes(out, png)
        return out

    def close(self) -> None:
        """Quit the browser."""
        self.driver.quit()


def open_page(url: str, *, width: int = 1280, height: int = 1000) -> Page:
    """A headless chromium showing ``url`` (``BrowserUnavailable`` without chromium / chromedriver)."""
    browser, driver_path = chromium_paths()
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError as exc:
        raise BrowserUnavailable(f"the browser needs selenium ({exc}): {install_command('dev')}") from exc
    options = webdriver.ChromeOptions()
    options.binary_location = browser
    for flag in (
        "--headless=new",
        "--no-sandbox",
        "--disable-dev-shm-usage",
        "--disable-gpu",
        f"--window-size={width},{height}",
    ):
        options.add_argument(flag)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})  # Page.console_errors reads the console
    driver = webdriver.Chrome(service=Service(executable_path=driver_path), options=options)
    driver.set_page_load_timeout(60)
    driver.get(url)
    return Page(driver)
