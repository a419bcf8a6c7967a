"""``render_mode="human"`` for the 2D envs: a pygame window that shows RGB frames.

pygame is an optional extra (``pip install "steer-envs[human]"``) and is
imported only when a :class:`HumanView` is made; without it,
:class:`~steer_envs.core.extras.MissingExtraError` (an ``ImportError`` and
Gymnasium's ``DependencyNotInstalled``) names the extra. The window
follows Gymnasium's classic-control envs: it opens on the first frame, each
frame pumps pygame's events and waits for the clock (``fps`` frames per
second), and :meth:`HumanView.close` quits pygame.
"""

from __future__ import annotations

import os
from types import ModuleType
from typing import Any

import numpy as np

from steer_envs.core.extras import install_command, require
from steer_envs.core.validation import real_scalar

#: how users get pygame
INSTALL_HINT = install_command("human")


def import_pygame() -> ModuleType:
    """The ``pygame`` module, or :class:`~steer_envs.core.extras.MissingExtraError` with the install hint."""
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")  # no banner on stdout (logs stay clean)
    return require("pygame", "human", 'render_mode="human"')


class HumanView:
    """A pygame window that shows ``(H, W, 3)`` uint8 frames at ``fps`` frames per second.

    >>> view = HumanView(fps=30, caption="SoupScoop")  # doctest: +SKIP
    >>> view.show(env.unwrapped.draw_frame(pos, trail))  # doctest: +SKIP
    >>> view.close()  # doctest: +SKIP
    """

    def __init__(self, fps: float, caption: str = "steer-envs") -> None:
        self.fps = real_scalar(fps, "fps", low=0.0, low_inclusive=False, owner="HumanView")
        self.caption = str(caption)
        import_pygame()  # fail when the env is made, not at its first frame
        self._screen: Any = None
        self._clock: Any = None

    @property
    def is_open(self) -> bool:
        """Whether the window is open (it opens on the first :meth:`show`)."""
        return self._screen is not None

    def show(self, frame: np.ndarray) -> None:
        """Draw ``frame`` (``(H, W, 3)`` uint8) in the window, opening or resizing it as needed."""
        image = np.asarray(frame)
        if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
            raise ValueError(f"HumanView.show: frame must be an (H, W, 3) uint8 array, got {image.dtype} {image.shape}")
        pygame = import_pygame()
        size = (image.shape[1], image.shape[0])  # pygame sizes are (width, height)
        if self._screen is None or self._screen.get_size() != size:
            pygame.display.init()
            pygame.display.set_caption(self.caption)
            self._screen = pygame.display.set_mode(size)
        if self._clock is None:
            self._clock = pygame.time.Clock()
        self._screen.blit(pygame.surfarray.make_surface(image.swapaxes(0, 1)), (0, 0))
        pygame.event.pump()
        self._clock.tick(self.fps)
        pygame.display.flip()

    def close(self) -> None:
        """Close the window and quit pygame (a no-op if it never opened)."""
        if self._screen is None:
            return
        pygame = import_pygame()
        pygame.display.quit()
        pygame.quit()
        self._screen = None
        self._clock = None
