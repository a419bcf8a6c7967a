"""Record a session, save it, replay it to the same frames; its video; the file checks; ``steer-ui replay``.

Replays are compared bit for bit (frames, plans, panels): the same process, inference backend and one
network thread make every call deterministic. Across machines or backends only float tolerance holds
(steer_envs.ui.recording says why); the frame digests then say where a replay drifted.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from steer_envs.ui import PushSession, Session, SteerSettings
from steer_envs.ui.cli import main
from steer_envs.ui.recording import (
    RECORDING_FORMAT,
    Recording,
    RecordingError,
    json_options,
    load_recording,
    recording_json,
    save_recording,
)
from steer_envs.ui.replay import replay
from steer_envs.ui.video import encode_video, replay_video
from steer_envs.utils.threads import limit_threads


@pytest.fixture(scope="module")
def maze(
    tmp_path_factory: pytest.TempPathFactory,
) -> Iterator[tuple[Path, Session, list[np.ndarray], list[np.ndarray]]]:
    """A few interactions in maze2d (small batches), saved: the file, the session, its frames and its plans."""
    path = tmp_path_factory.mktemp("maze") / "maze.json"
    with limit_threads(1, 1):
        session = Session(seed=2, settings=SteerSettings(sampler="GD", batch=8))
        frames, plans = [session.frame()], []
        start = session.state
        sketch = session.pixels.to_pixels(start + np.array([[0.0, 0.0], [0.0, 1.5], [1.0, 2.0]]))
        plans.append(session.steer_pixels("sketch", sketch).plans)
        session.execute()
        frames.append(session.frame())
        session.configure(sampler="SS", batch=4, guide_ratio=30)
        plans.append(session.steer_pixels("point", [session.pixels.to_pixels(session.state + 1.0)]).plans)
        session.nudge(session.state + np.array([0.3, 0.0]))
        frames.append(session.frame())
        session.execute()  # unsteered: the plans of the nudge expired
        session.reset(seed=5)
        session.execute()
        frames.append(session.frame())
        save_recording(session.recording(), path)
    yield path, session, frames, plans
    session.close()


def test_maze2d_replays_to_the_same_frames_and_plans(maze) -> None:  # type: ignore[no-untyped-def]
    path, session, frames, plans = maze
    recording = load_recording(path)
    assert [e["op"] for e in recording.events] == [
        "steer", "step", "configure", "steer", "nudge", "steer", "step", "reset", "steer", "step",
    ]  # fmt: skip
    assert recording.session["settings"]["sampler"] == "GD" and recording.events[2]["knobs"]["guide_ratio"] == 30
    with limit_threads(1, 1):
        replayed = replay(recording)
    try:
        assert replayed.identical and replayed.mismatches == []
        steers = [o.plans for e, o in zip(recording.events, replayed.outcomes, strict=True) if e["op"] == "steer"]
        np.testing.assert_array_equal(steers[0], plans[0])
        np.testing.assert_array_equal(steers[1], plans[1])
        np.testing.assert_array_equal(replayed.frames[0], frames[0])
        np.testing.assert_array_equal(replayed.frames[-1], frames[-1])
        np.testing.assert_array_equal(replayed.session.state, session.state)
    finally:
        replayed.session.close()


def test_soup_scoop_replays_pushes_and_a_tampered_frame_is_found(tmp_path: Path) -> None:
    with limit_threads(1, 1):
        session = PushSession("soup-scoop", seed=1)
        session.execute()
        session.push_pixel(96.0, 224.0)  # (-2, -6): into the soup
        session.configure(execute=30)
        session.execute()
        session.push([4.0, -2.0])
        session.execute()
        frame, panel = session.frame(), session.panel()
        recording = session.recording()
        session.close()
        assert recording.events[1] == {"op": "push", "to": [-2.0, -6.0]}  # no frame rendered until the next step
        replayed = replay(Recording.from_dict(json.loads(recording_json(recording))))
        assert replayed.identical
        np.testing.assert_array_equal(replayed.frames[-1], frame)
        assert replayed.session.panel() == panel
        replayed.session.close()

        events = [dict(e) for e in recording.events]
        events[4]["to"] = [4.0, -1.0]  # another push than the one recorded: the frames after it differ
        tampered = replay(
            Recording(recording.domain, recording.seed, recording.session, tuple(events), recording.start_frame)
        )
        tampered.session.close()
        assert tampered.mismatches and tampered.mismatches[0] == 5  # the push itself renders no frame; the step does


@pytest.mark.parametrize(
    ("mutate", "match"),
    [
        (lambda d: d.update(format=99), "'format' is 99"),
        (lambda d: d.pop("events"), r"missing \['events'\]"),
        (lambda d: d.update(domain="pinball"), "'domain' is 'pinball'"),
        (lambda d: d.update(seed=-3), "'seed'"),
        (lambda d: d["session"].update(kind="steer"), "'session.kind'"),
        (lambda d: d["events"].append({"op": "teleport"}), r"events\[1\]"),
        (lambda d: d["events"].append({"op": "push"}), r"events\[1\] \('push'\) has unknown \[\] / lacks \['to'\]"),
    ],
)
def test_a_bad_recording_file_is_named_in_the_error(tmp_path: Path, mutate, match) -> None:  # type: ignore[no-untyped-def]
    good = Recording("soup-scoop", 1, {"kind": "push"}, ({"op": "step"},))
    data = good.as_dict()
    mutate(data)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    with pytest.raises(RecordingError, match=match) as info:
        load_recording(path)
    assert str(path) in str(info.value)


def test_unreadable_files_and_atomic_saves(tmp_path: Path) -> None:
    with pytest.raises(RecordingError, match=r"missing\.json: cannot read"):
        load_recording(tmp_path / "missing.json")
    (tmp_path / "text.json").write_text("steer me")
    with pytest.raises(RecordingError, match=r"text\.json: not a JSON recording"):
        load_recording(tmp_path / "text.json")
    good = Recording("maze2d", 0, {"kind": "steer"}, ())
    save_recording(good, tmp_path / "r.json")
    assert (
        load_recording(tmp_path / "r.json") == good and load_recording(tmp_path / "r.json").format == RECORDING_FORMAT
    )
    with pytest.raises(TypeError, match="Recording"):
        save_recording({"format": 1}, tmp_path / "r.json")  # type: ignore[arg-type]
    assert load_recording(tmp_path / "r.json") == good and sorted(p.name for p in tmp_path.iterdir()) == [
        "r.json", "text.json",
    ]  # fmt: skip
    assert json_options({"cache_dir": "/x", "setup": object()}) == ({"cache_dir": "/x"}, ["setup"])
    with pytest.raises(RecordingError, match=r"controller options \['setup'\] are not JSON"):
        replay(Recording("polygon-nav", 0, {"kind": "push", "unrecorded_options": ["setup"]}, ()))


def test_videos_of_a_replay(maze, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    import imageio.v3 as iio

    with limit_threads(1, 1):
        path, replayed = replay_video(load_recording(maze[0]), tmp_path / "maze.mp4")
    assert replayed.identical
    video = iio.imread(path)
    assert video.shape[0] == 10 and video.shape[1] % 16 == 0 and video.shape[1] >= 512
    frame = np.zeros((8, 8, 3), dtype=np.uint8)
    assert encode_video([frame] * 3, "gif", fps=2)[:6] == b"GIF89a"
    with pytest.raises(ValueError, match="fmt"):
        encode_video([frame], "avi")
    with pytest.raises(ValueError, match="empty"):
        encode_video([], "gif")


def test_steer_ui_replay_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with limit_threads(1, 1):
        session = PushSession("soup-scoop", seed=1)
        session.execute()
        session.push([-2.0, -6.0])
        session.execute()
        save_recording(session.recording(), tmp_path / "scoop.json")
        session.close()
    command = ["replay", str(tmp_path / "scoop.json"), "--video", str(tmp_path / "s.gif")]
    done = subprocess.run(
        [sys.executable, "-m", "steer_envs.ui", *command], capture_output=True, text=True, timeout=300, check=False
    )
    assert done.returncode == 0, done.stderr
    assert "3 events of soup-scoop replayed; every recorded frame matched" in done.stdout
    assert (tmp_path / "s.gif").read_bytes()[:6] == b"GIF89a"

    for argv in (["replay", "--help"], ["--help"]):
        with pytest.raises(SystemExit) as exit_info:
            main(argv)
        assert exit_info.value.code == 0
    assert "steer-ui replay FILE" in capsys.readouterr().out
    with pytest.raises(SystemExit) as exit_info:
        main(["replay", str(tmp_path / "scoop.json"), "--video", str(tmp_path / "scoop.avi")])
    assert exit_info.value.code == 2 and "--video must end in .mp4 or .gif" in capsys.readouterr().err
    assert main(["replay", str(tmp_path / "nothing.json")]) == 2
    assert "nothing.json: cannot read" in capsys.readouterr().err
    data = json.loads((tmp_path / "scoop.json").read_text())
    data["events"][2]["frame"] = "0" * 64
    (tmp_path / "drift.json").write_text(json.dumps(data))
    with limit_threads(1, 1):
        assert main(["replay", str(tmp_path / "drift.json")]) == 1
    assert "frames differ after events[2] (step)" in capsys.readouterr().err


def test_a_log_too_long_to_record_says_so(monkeypatch: pytest.MonkeyPatch) -> None:
    from types import SimpleNamespace

    from steer_envs.ui import recording

    monkeypatch.setattr(recording, "MAX_EVENTS", 2)
    log = recording.SessionLog()
    for _ in range(3):
        log.add("step")
    assert len(log.events) == 2 and log.overflowed
    with pytest.raises(RecordingError, match="more than 2 calls"):
        recording.recording_of(SimpleNamespace(name="soup-scoop"), {"kind": "push", "seed": 0}, log)
