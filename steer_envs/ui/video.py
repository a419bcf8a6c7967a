"""A rollout as a video: each frame with what the page draws over it (plans, flows, cuts, modes), as MP4 or GIF.

:func:`annotated_frame` draws a session's current frame the way the page
does (the steered plans, the chosen one and the sketch or point of an ITPS
domain; a push domain's overlays), scaled up so lines stay thin;
:func:`write_video` encodes frames as H.264 MP4 (imageio with its
imageio-ffmpeg backend, the ``ui`` extra) or as a GIF, written atomically;
:func:`replay_video` replays a :class:`~steer_envs.ui.recording.Recording`
into one.

>>> frame = np.zeros((4, 4, 3), dtype=np.uint8)
>>> len(encode_video([frame, frame], "gif", fps=2)) > 0
True
"""

from __future__ import annotations

import base64
import io
import os
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from steer_envs.core.validation import integer, one_of, real_scalar

__all__ = ["VIDEO_FORMATS", "annotated_frame", "encode_video", "replay_video", "write_video"]

#: the containers :func:`write_video` writes (by the file's suffix)
VIDEO_FORMATS: tuple[str, ...] = ("mp4", "gif")
#: colours of the page (static/app.js)
COLORS = {"sketch": "#c81ec8", "plan": "#149f9f", "collide": "#f08c1e", "chosen": "#1b2a8f", "agent": "#dc1e1e"}
#: frames are drawn at least this many pixels on their longer side (and in multiples of 16, for H.264)
MIN_SIDE = 512


def _scale(image: np.ndarray) -> int:
    return max(1, -(-MIN_SIDE // max(image.shape[:2])))


def _xy(points: Any, scale: int) -> list[tuple[float, float]]:
    return [(float(u) * scale, float(v) * scale) for u, v in np.asarray(points, dtype=np.float64).reshape(-1, 2)]


def _dot(draw: Any, p: tuple[float, float], radius: float, color: str) -> None:
    draw.ellipse([p[0] - radius, p[1] - radius, p[0] + radius, p[1] + radius], fill=color)


def _draw_plans(draw: Any, session: Any, outcome: Any, scale: int) -> None:
    """The steered batch (orange: through a wall), the chosen plan (thick) and the sketch / point."""
    plans = session.pixels.to_pixels(outcome.plans)
    for i, plan in enumerate(plans):
        if i != outcome.chosen:
            hit = outcome.collides is not None and bool(outcome.collides[i])
            draw.line(_xy(plan, scale), fill=COLORS["collide" if hit else "plan"], width=max(1, scale))
    draw.line(_xy(plans[outcome.chosen], scale), fill=COLORS["chosen"], width=3 * scale)
    interaction = outcome.interaction
    if interaction is not None:
        data = getattr(interaction, "points", None)
        drawn = _xy(session.pixels.to_pixels(np.asarray(data if data is not None else interaction.target)), scale)
        if len(drawn) == 1:
            _dot(draw, drawn[0], 4 * scale, COLORS["sketch"])
        else:
            draw.line(drawn, fill=COLORS["sketch"], width=3 * scale)


def _draw_overlay(image: Any, draw: Any, overlay: Mapping[str, Any], data: Any, scale: int) -> None:
    """One of a push domain's overlays (:data:`~steer_envs.ui.domains.OVERLAY_KINDS`), as static/app.js draws it."""
    from PIL import Image

    kind, legend = overlay["kind"], overlay["legend"]
    color = legend[0][1] if legend else COLORS["plan"]
    if not data:
        return
    if kind == "image":
        raw = base64.b64decode(str(data["src"]).split(",", 1)[1])
        tint = Image.open(io.BytesIO(raw)).convert("RGBA").resize(image.size, Image.Resampling.NEAREST)
        image.alpha_composite(tint)
    elif kind == "arrows":
        for u, v, du, dv in data:
            start, end = _xy([u, v], scale)[0], _xy([u + du, v + dv], scale)[0]
            draw.line([start, end], fill=color, width=max(1, scale))
            _dot(draw, end, 1.5 * scale, color)
    elif kind == "lines":
        for line in data:
            draw.line(_xy(line, scale), fill=color, width=2 * scale)
    elif kind == "markers":
        for p in _xy(data, scale):
            _dot(draw, p, 4 * scale, color)
    elif kind == "strip":
        rows, steps = data["rows"], max(1, int(data["steps"]))
        bar, left = 6 * scale, 40 * scale
        cell = (image.size[0] - left - 4 * scale) / steps
        y = image.size[1] - len(rows) * (bar + 2 * scale) - 2 * scale
        draw.rectangle([0, y - 2 * scale, image.size[0], image.size[1]], fill=(255, 255, 255, 200))
        for label, modes in rows:
            draw.text((3 * scale, y), str(label), fill="#222222")
            for i, k in enumerate(modes):
                fill = legend[k][1] if 0 <= k < len(legend) else "#999999"
                draw.rectangle([left + i * cell, y, left + (i + 1) * cell, y + bar], fill=fill)
            y += bar + 2 * scale


def annotated_frame(session: Any, outcome: Any = None) -> np.ndarray:
    """``session``'s frame with what the page draws over it: ``outcome``'s plans (a steering outcome) or the
    push domain's overlays; scaled by an integer factor to at least :data:`MIN_SIDE` pixels a side."""
    from PIL import Image, ImageDraw

    from steer_envs.ui.outcomes import SteerOutcome
    from steer_envs.ui.push_session import PushSession

    frame = session.frame()
    scale = _scale(frame)
    image = Image.fromarray(frame).convert("RGBA")
    if scale > 1:
        image = image.resize((frame.shape[1] * scale, frame.shape[0] * scale), Image.Resampling.NEAREST)
    draw = ImageDraw.Draw(image, "RGBA")
    if isinstance(session, PushSession):
        data = session.overlays(full=True)
        for overlay in session.domain.declaration(session.name)["overlays"]:
            _draw_overlay(image, draw, overlay, data.get(overlay["name"]), scale)
    elif isinstance(outcome, SteerOutcome):
        _draw_plans(draw, session, outcome, scale)
    agent = _xy(session.pixels.to_pixels(session.state), scale)[0]
    _dot(draw, agent, 3 * scale, COLORS["agent"])
    return np.asarray(image.convert("RGB"))


def _even(frame: np.ndarray) -> np.ndarray:
    """Pad a frame to multiples of 16 pixels (H.264's macro blocks) with white."""
    h, w = frame.shape[:2]
    out = np.full((-(-h // 16) * 16, -(-w // 16) * 16, 3), 255, dtype=np.uint8)
    out[:h, :w] = frame
    return out


def encode_video(frames: Sequence[np.ndarray], fmt: str = "mp4", fps: float = 4.0) -> bytes:
    """``frames`` (``(H, W, 3)`` uint8, one size) encoded as ``fmt`` (:data:`VIDEO_FORMATS`) at ``fps``."""
    fmt = one_of(fmt, "fmt", VIDEO_FORMATS, owner="encode_video")
    fps = real_scalar(fps, "fps", low=0.1, high=120.0, owner="encode_video")
    if len(frames) == 0:
        raise ValueError("encode_video: `frames` is empty; a video needs at least one frame")
    stack = [np.asarray(f, dtype=np.uint8) for f in frames]
    if any(f.ndim != 3 or f.shape[2] != 3 or f.shape != stack[0].shape for f in stack):
        raise ValueError(f"encode_video: `frames` must be (H, W, 3) uint8 of one size, got {stack[0].shape} and others")
    if fmt == "gif":
        from PIL import Image

        buffer = io.BytesIO()
        images = [Image.fromarray(f) for f in stack]
        images[0].save(buffer, format="GIF", save_all=True, append_images=images[1:], duration=int(1000 / fps), loop=0)
        return buffer.getvalue()
    from steer_envs.core.extras import require

    require("imageio_ffmpeg", "ui", "an MP4 export")
    import imageio.v2 as imageio

    with tempfile.TemporaryDirectory(prefix="steer-ui-video-") as tmp:
        path = os.path.join(tmp, "video.mp4")
        writer = imageio.get_writer(
            path, format="FFMPEG", mode="I", fps=fps, codec="libx264", pixelformat="yuv420p", macro_block_size=16
        )
        try:
            for frame in stack:
                writer.append_data(_even(frame))
        finally:
            writer.close()
        return Path(path).read_bytes()


def write_video(path: str | os.PathLike[str], frames: Sequence[np.ndarray], fps: float = 4.0) -> Path:
    """Write ``frames`` to ``path`` (``.mp4`` or ``.gif``, by its suffix) atomically; returns the path."""
    from steer_envs.io import atomic_write_bytes

    target = Path(path)
    fmt = target.suffix.lower().lstrip(".")
    if fmt not in VIDEO_FORMATS:
        raise ValueError(f"write_video: `path` must end in .mp4 or .gif, got {str(path)!r}")
    atomic_write_bytes(target, encode_video(frames, fmt, fps))
    return target


def replay_video(
    recording: Any,
    path: str | os.PathLike[str],
    *,
    fps: float = 4.0,
    controller_options: Mapping[str, Any] | None = None,
    max_frames: int = 10_000,
) -> tuple[Path, Any]:
    """Replay ``recording`` and write its rollout to ``path`` (a frame per event, plans drawn).

    Returns the path and the :class:`~steer_envs.ui.replay.Replayed` (its session closed).
    """
    from steer_envs.ui.replay import replay

    max_frames = integer(max_frames, "max_frames", low=1, owner="replay_video")
    frames: list[np.ndarray] = []

    def grab(index: int, event: Mapping[str, Any], session: Any, outcome: Any) -> None:
        if len(frames) < max_frames:
            frames.append(annotated_frame(session, outcome))

    replayed = replay(recording, controller_options=controller_options, on_event=grab)
    try:
        if not frames:
            frames.append(annotated_frame(replayed.session))
        return write_video(path, frames, fps), replayed
    finally:
        replayed.session.close()
