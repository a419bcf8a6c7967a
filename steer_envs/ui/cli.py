"""``steer-ui``: steer a policy by hand in the browser (``python -m steer_envs.ui``).

    steer-ui                    # http://127.0.0.1:8765, Maze2D-Large, the shipped DP
    steer-ui --policy act --port 9000 --open
    steer-ui --domain blockstack  # the robot arm: click a cube in the camera image
    steer-ui --domain soup-scoop  # TLI: push the spoon, watch LTL-DS recover
    steer-ui replay session.json --video rollout.mp4  # a saved session, again, as a video

Binds to 127.0.0.1. Another interface needs ``--allow-remote`` (and warns:
anyone who can reach the port can drive the server); the server answers only
requests that name it by this machine's names, the bound address or an
``--allowed-host``, and only WebSockets from its own page
(:mod:`steer_envs.ui.access`).
"""

from __future__ import annotations

import argparse
import sys
import webbrowser
from collections.abc import Sequence

from steer_envs.baselines.diffusion.acceleration import ACCELERATIONS
from steer_envs.core.extras import MissingExtraError, require
from steer_envs.ui.access import ANY_INTERFACE, allowed_hosts, is_local
from steer_envs.ui.domains import DEFAULT_ENV, DOMAINS
from steer_envs.ui.session import POLICY_KINDS
from steer_envs.utils.fields import build_from


def build_parser() -> argparse.ArgumentParser:
    """The ``steer-ui`` argument parser."""
    parser = argparse.ArgumentParser(
        prog="steer-ui",
        description="Steer a robot policy by hand in the browser: sketch, point, nudge; or push a controller.",
        epilog="steer-ui replay FILE [--video OUT.mp4]: replay a saved session (steer-ui replay --help).",
    )
    parser.add_argument("--host", default="127.0.0.1", help="interface to bind (default: 127.0.0.1, this machine only)")
    parser.add_argument(
        "--allow-remote",
        action="store_true",
        help="let --host be an interface other than this machine's (anyone who can reach the port can steer)",
    )
    parser.add_argument(
        "--allowed-host",
        action="append",
        default=[],
        metavar="NAME",
        help="another Host name clients may use (repeatable; e.g. the machine's name on the network)",
    )
    parser.add_argument("--port", type=int, default=8765, help="TCP port (default: 8765; 0 picks a free one)")
    parser.add_argument("--domain", choices=sorted(DOMAINS), default="maze2d", help="what to steer (default: maze2d)")
    parser.add_argument("--env", default=None, help=f"another env id of the domain (maze2d default: {DEFAULT_ENV})")
    parser.add_argument(
        "--policy",
        choices=POLICY_KINDS,
        default=None,
        help="shipped policy kind of a steered domain (default: the domain's: dp for maze2d, blockstack, kitchen)",
    )
    parser.add_argument("--checkpoint", default=None, help="a checkpoint of --policy (default: the shipped one)")
    parser.add_argument(
        "--accelerate",
        choices=ACCELERATIONS,
        default="fastest",
        help="the DP network's inference mode (default: fastest, OpenVINO where installed, else ONNX Runtime or trace)",
    )
    parser.add_argument(
        "--cache-dir",
        default=None,
        help="where a push domain keeps what it trains (GLiDE's classifier; default: ~/.cache/steer-envs/ui)",
    )
    parser.add_argument("--seed", type=int, default=0, help="first start state and noise seed (default: 0)")
    parser.add_argument("--workers", type=int, default=2, help="steering calls run at once (default: 2)")
    parser.add_argument("--threads", type=int, default=1, help="torch threads per call (default: 1)")
    parser.add_argument("--open", action="store_true", help="open the page in the default browser")
    return parser


def build_replay_parser() -> argparse.ArgumentParser:
    """The ``steer-ui replay`` argument parser."""
    parser = argparse.ArgumentParser(
        prog="steer-ui replay",
        description="Replay a session saved by steer-ui (its 'Save session' button, or save_recording) and check "
        "that it reaches the same frames; optionally write the rollout as a video with the plans drawn.",
        epilog="Exit status: 0 the frames matched the recording's, 1 some differed, 2 usage or file errors.",
    )
    parser.add_argument("recording", metavar="FILE", help="the saved session (.json)")
    parser.add_argument("--video", default=None, metavar="OUT", help="write the rollout here (.mp4 or .gif)")
    parser.add_argument("--fps", type=float, default=4.0, help="frames per second of the video (default: 4)")
    parser.add_argument(
        "--cache-dir", default=None, help="where a GLiDE domain's classifier is kept (default: ~/.cache/steer-envs/ui)"
    )
    return parser


def replay_main(argv: Sequence[str]) -> int:
    """``steer-ui replay``: 0 when the replayed frames match the recording's, 1 when some differ, 2 on errors."""
    parser = build_replay_parser()
    args = parser.parse_args(argv)
    if args.video is not None and not str(args.video).lower().endswith((".mp4", ".gif")):
        parser.error(f"--video must end in .mp4 or .gif, got {args.video}")
    if not 0.1 <= args.fps <= 120:
        parser.error(f"--fps must be in [0.1, 120], got {args.fps}")
    from steer_envs.ui.recording import RecordingError, load_recording
    from steer_envs.ui.replay import replay

    try:
        recording = load_recording(args.recording)
        glide = DOMAINS[recording.domain].controller in ("glide-planning", "glide-bc-arm")
        options = {"cache_dir": args.cache_dir} if args.cache_dir and glide else None
        if args.video is not None:
            from steer_envs.ui.video import replay_video

            _, replayed = replay_video(recording, args.video, fps=args.fps, controller_options=options)
        else:
            replayed = replay(recording, controller_options=options)
            replayed.session.close()
    except (RecordingError, MissingExtraError) as exc:
        print(f"steer-ui replay: {exc}", file=sys.stderr)
        return 2
    events = len(recording.events)
    if args.video is not None:
        print(f"steer-ui replay: wrote {args.video}")
    if replayed.identical:
        print(f"steer-ui replay: {events} events of {recording.domain} replayed; every recorded frame matched")
        return 0
    where = ", ".join(
        "the opening" if i < 0 else f"events[{i}] ({recording.events[i]['op']})" for i in replayed.mismatches[:5]
    )
    print(f"steer-ui replay: {events} events replayed; frames differ after {where}", file=sys.stderr)
    return 1


def main(argv: Sequence[str] | None = None) -> int:
    """Run the server until Ctrl-C (``replay``: :func:`replay_main`); exit code 2 for usage errors."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["replay"]:
        return replay_main(argv[1:])
    parser = build_parser()
    args = parser.parse_args(argv)
    if not 0 <= args.port <= 65535:
        parser.error(f"--port must be in [0, 65535], got {args.port}")
    if args.workers < 1 or args.threads < 1 or args.seed < 0:
        parser.error("--workers and --threads must be >= 1 and --seed >= 0")
    if not is_local(args.host) and not args.allow_remote:
        parser.error(f"--host {args.host} serves beyond this machine: add --allow-remote to mean it")
    if args.host in ANY_INTERFACE and not args.allowed_host:
        parser.error(f"--host {args.host} has no name to check requests against: add --allowed-host NAME")
    try:
        for module in ("fastapi", "uvicorn", "websockets"):
            require(module, "ui", "steer-ui")
    except MissingExtraError as exc:
        print(exc, file=sys.stderr)
        return 2
    import torch
    import uvicorn

    from steer_envs.ui.server import UIConfig, create_app

    torch.set_num_threads(args.threads)
    if not is_local(args.host):
        print(
            f"warning: binding to {args.host}: anyone who can reach port {args.port} can steer this server's robot",
            file=sys.stderr,
        )
    config = build_from(UIConfig, args, allowed_hosts=allowed_hosts(args.host, args.allowed_host))
    try:
        app = create_app(config)
    except (ValueError, TypeError) as exc:
        print(f"steer-ui: {exc}", file=sys.stderr)
        return 2
    server = uvicorn.Server(uvicorn.Config(app, host=args.host, port=args.port, log_level="warning"))
    url = f"http://{'127.0.0.1' if args.host in ('0.0.0.0', '::') else args.host}:{args.port}"
    if DOMAINS[args.domain].controller in ("glide-planning", "glide-bc-arm"):
        print("steer-ui: GLiDE's mode classifier is trained on first use (minutes on one core), then cached")
    print(f"steer-ui: loading the policy, then serving {url} (Ctrl-C stops)", flush=True)
    if args.open:
        webbrowser.open(url)
    server.run()
    return 0


if __name__ == "__main__":
    sys.exit(main())
