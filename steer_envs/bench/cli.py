"""``steer-bench``: list suites, run them (resumably), report results.

Exit status: 0 success; 1 some trials failed (they are logged in
``failures.jsonl`` and re-run by the next ``run``), or a suite's own figures
could not be drawn (``report --plots``); 2 bad usage or configuration, as one
line on stderr: an unknown suite/env/method/parameter or a bad value, a
plugin that fails to import, more than
:data:`~steer_envs.bench.runner.MAX_PLANNED_TRIALS` planned trials, an
``--out`` / ``DIR`` / ``--plots-dir`` that is empty, a file, under a file,
unwritable, or not a steer-bench directory (a ``manifest.json`` that is not
a manifest, a ``results.jsonl`` that is a folder), a directory locked by
another run, a missing optional dependency or an executor that cannot start,
a ``--param`` that names code (a loader) other than a registered one
without ``--allow-import``; 130 interrupted (finished trials are on disk). Bad lines of
``results.jsonl`` never stop ``run`` or ``report``: they are skipped with a
note (``run`` moves them to ``discarded.jsonl``).
Set ``STEER_BENCH_DEBUG=1`` to get tracebacks instead of one-line errors.

>>> main(["list", "selftest"])
suites:
  selftest: Runner self-check: pi by Monte Carlo vs. stratified sampling (no envs needed).
      methods: mc, stratified
      metrics: pi, abs_error, samples_per_s
      params: samples=10000, sleep=0.0, fail_seeds=[]  (--trials sets samples)
      default seeds: 4
      reference numbers: 1 (pi = 3.14159...)
0
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

from steer_envs.bench.executors import EXECUTORS, ExecutorStartError
from steer_envs.bench.params import check_callable_params
from steer_envs.bench.report import FORMATS, render, render_markdown, summarize
from steer_envs.bench.store import (
    DISCARDED_FILE,
    PLOTS_DIR,
    RESULTS_FILE,
    SUMMARY_FILE,
    StoreLockedError,
    atomic_write_text,
    check_output_dir,
    load_results,
)
from steer_envs.bench.suite import Suite, get_suite, load_plugins, suites
from steer_envs.utils.cli import parse_key_value
from steer_envs.utils.fields import same_named

EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130


class _Parser(argparse.ArgumentParser):
    """``argparse`` with usage errors as one line on stderr (exit 2)."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {_one_line(message)} (see {self.prog} --help)\n")


def _one_line(message: str) -> str:
    return " | ".join(line.strip() for line in str(message).splitlines() if line.strip())


def _path(text: str) -> Path:
    """argparse type for a folder option: a non-empty path (``''`` would silently mean the current folder)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("expected a folder path, got an empty string")
    if "\x00" in text:
        raise argparse.ArgumentTypeError("a path must not contain NUL characters")
    return Path(text)


def _param(text: str) -> tuple[str, Any]:
    """argparse type for ``--param``: :func:`parse_key_value` with argparse's error type."""
    try:
        return parse_key_value(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {value}")
    return value


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``steer-bench`` (``--help`` on every sub-command).

    >>> build_parser().parse_args(["run", "smoke", "--param", "episodes=3"]).param
    [('episodes', 3)]
    """
    from steer_envs import __version__

    parser = _Parser(
        prog="steer-bench",
        description="Benchmark runner of steer-envs: suites of trials over the registered envs, "
        "results as resumable JSON lines, reports beside the thesis's numbers.",
    )
    parser.add_argument("--version", action="version", version=f"steer-bench (steer-envs {__version__})")
    sub = parser.add_subparsers(dest="command", metavar="{list,run,report}", required=True)

    plugin = _Parser(add_help=False)
    plugin.add_argument(
        "--plugin",
        action="append",
        default=[],
        metavar="MODULE",
        help="import MODULE first (it registers extra suites); also $STEER_BENCH_PLUGINS",
    )

    p_list = sub.add_parser("list", parents=[plugin], help="list suites, their envs, methods and metrics")
    p_list.add_argument("suite", nargs="?", help="show only this suite")
    _add_run_parser(sub, plugin)
    p_report = sub.add_parser("report", parents=[plugin], help="tables (and plots) from a results directory")
    p_report.add_argument("dir", type=_path, help="a --out directory of `steer-bench run`")
    p_report.add_argument("--format", choices=FORMATS, default="md", help="output format (default: md)")
    p_report.add_argument("--plots", action="store_true", help="also write PNG figures")
    p_report.add_argument("--plots-dir", type=_path, metavar="DIR", help="where the PNGs go (default: DIR/plots)")
    return parser


def _add_run_parser(sub: Any, plugin: argparse.ArgumentParser) -> None:
    """The ``run`` sub-command: what to run, how many, where, on which executor."""
    p_run = sub.add_parser(
        "run",
        parents=[plugin],
        help="run (or resume) a suite",
        description="Run SUITE into --out; an existing --out is resumed (finished trials skipped; when all "
        "are done, nothing runs and the report is printed). --fresh starts over.",
    )
    p_run.add_argument("suite", help="suite name (see `steer-bench list`)")
    p_run.add_argument("--env", nargs="+", action="extend", metavar="ID", help="only these env ids (default: all)")
    p_run.add_argument("--method", nargs="+", action="extend", metavar="NAME", help="only these methods (default: all)")
    p_run.add_argument("--seeds", type=_positive_int, metavar="N", help="seeds 0..N-1 (default: the suite's)")
    p_run.add_argument(
        "--trials",
        type=_positive_int,
        metavar="N",
        help="rollouts per trial (the suite's trials parameter, e.g. smoke's episodes)",
    )
    p_run.add_argument(
        "--param",
        type=_param,
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="set a suite parameter (VALUE parsed as JSON if it is JSON); see `steer-bench list SUITE`",
    )
    p_run.add_argument(
        "--allow-import",
        action="store_true",
        help="let --param values that name code (e.g. loader=module:function) import and run any module, "
        "not only the registered loaders (e.g. loader=pretrained); it runs that code",
    )
    p_run.add_argument(
        "--workers",
        type=_positive_int,
        metavar="N",
        help="parallel workers: a local process pool when N > 1; Ray: CPUs to use (default: 1; Ray: all CPUs)",
    )
    p_run.add_argument("--executor", choices=EXECUTORS, default="local", help="where trials run (default: local)")
    p_run.add_argument(
        "--address", metavar="ADDR", help="Ray cluster address ('auto', 'ray://host:10001'); default: start a local Ray"
    )
    p_run.add_argument("--out", type=_path, metavar="DIR", help="results directory (default: runs/SUITE)")
    p_run.add_argument(
        "--fresh",
        action="store_true",
        help="start over instead of resuming: the earlier results of DIR (results.jsonl, failures.jsonl, "
        "discarded.jsonl, summary.md, manifest.json, plots/) are moved to DIR/previous/<UTC time>/ "
        "(nothing is deleted; other files stay) and every planned trial runs",
    )
    p_run.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="show (or hide) the progress bar (default: shown only when stderr is a terminal)",
    )


def _describe(suite: Suite) -> list[str]:
    try:
        envs = [e for e in suite.env_list() if e is not None]
        methods = [m for m in suite.method_list() if m is not None]
    except Exception as exc:  # a lazy axis failed: show it instead of crashing `list`
        envs, methods = [f"<error: {exc}>"], []
    lines = [f"{suite.name}: {suite.description}"]
    if envs:
        lines.append(f"    envs ({len(envs)}): {', '.join(envs)}")
    if methods:
        lines.append(f"    methods: {', '.join(methods)}")
    if suite.metrics:
        lines.append(f"    metrics: {', '.join(m.name for m in suite.metrics)}")
    defaults = suite.defaults.to_json()
    if defaults:
        lines.append(
            f"    params: {', '.join(f'{k}={json.dumps(v)}' for k, v in defaults.items())}"
            + (f"  (--trials sets {suite.trials_param})" if suite.trials_param else "")
        )
    if suite.generate is None or suite.run_trial is not None:
        lines.append(f"    default seeds: {suite.default_seeds}")
    if suite.name == "quick":
        from steer_envs.bench.suites.quick import quick_sections

        lines.append(f"    tour of: {', '.join(s.name for s in quick_sections())}")
    if suite.quick is not None:
        lines.append(f"    in quick tour: {json.dumps(dict(suite.quick))}, seeds {suite.quick_seeds}")
    if suite.references:
        sources = ", ".join(sorted({r.source for r in suite.references}))
        lines.append(f"    reference numbers: {len(suite.references)} ({sources})")
    return lines


def cmd_list(args: argparse.Namespace) -> int:
    """Print the suites (or one suite) and the registered envs."""
    load_plugins(args.plugin)
    chosen = [get_suite(args.suite)] if args.suite else suites()
    print("suites:")
    for suite in chosen:
        print("  " + "\n  ".join(_describe(suite)))
    if not args.suite:
        import importlib.util

        import steer_envs
        from steer_envs.data.experts import has_expert
        from steer_envs.envs.registry import entry

        print("envs:")
        for env_id in steer_envs.env_ids():
            e = entry(env_id)
            module = e.entry_point.split(":")[0]
            tags = ["kinematic+vector" if e.kinematic else "single", "expert" if has_expert(env_id) else "no expert"]
            if importlib.util.find_spec(module) is None:
                tags.append("module missing")
            print(f"  {env_id}  ({', '.join(tags)})")
    return EXIT_OK


def cmd_run(args: argparse.Namespace, argv: Sequence[str]) -> int:
    """Run a suite, print notes, failures and the summary table."""
    from steer_envs.bench.runner import run_suite

    load_plugins(args.plugin)
    suite = get_suite(args.suite)
    params = dict(args.param)
    imports = check_callable_params(type(suite.defaults), params, suite=suite.name, allow_import=args.allow_import)
    if args.allow_import:
        named = ", ".join(f"{k}={v}" for k, v in imports.items()) or "none of the given --param values needs it"
        print(f"steer-bench: warning: --allow-import imports and runs arbitrary code: {named}", file=sys.stderr)
    out = args.out if args.out is not None else Path("runs") / suite.name
    given = same_named(run_suite, args, envs=args.env, methods=args.method, params=params, argv=list(argv))
    summary = run_suite(suite, out, **given)
    tables = summarize(summary.records)
    title = f"steer-bench {suite.name}: {len(summary.records)} trials in {out}"
    text = render_markdown(tables, title=title, notes=summary.notes)
    atomic_write_text(out / SUMMARY_FILE, text)
    print(text)
    if summary.all_done:
        print(
            f"all {summary.planned} trials already done in {out}; nothing was run (--fresh starts over)",
            file=sys.stderr,
        )
    else:
        print(
            f"{summary.planned} trials planned: {summary.skipped} already done, {summary.completed} run now, "
            f"{len(summary.failures)} failed -> {out}",
            file=sys.stderr,
        )
    if summary.interrupted:
        print("interrupted: finished trials are saved; run the same command again to resume", file=sys.stderr)
        return EXIT_INTERRUPTED
    if summary.failures:
        print(f"{len(summary.failures)} trial(s) failed (details in {out / 'failures.jsonl'}):", file=sys.stderr)
        for f in summary.failures[:10]:
            print(f"  {f.trial.label}: {(f.error or '').splitlines()[0]}", file=sys.stderr)
        return EXIT_FAILED
    return EXIT_OK


def cmd_report(args: argparse.Namespace) -> int:
    """Render the tables of a results directory; optionally write the plots."""
    load_plugins(args.plugin)
    manifest, records, read = load_results(args.dir)
    plots_dir = None
    if args.plots:
        plots_dir = check_output_dir(
            args.plots_dir if args.plots_dir is not None else args.dir / PLOTS_DIR, "--plots-dir"
        )
    elif args.plots_dir is not None:
        print("note: --plots-dir is ignored without --plots", file=sys.stderr)
    for note in read.describe(RESULTS_FILE):
        print(f"note: {args.dir}: {note}", file=sys.stderr)
    if read.torn_tail or read.bad_lines:
        print(f"note: the next `steer-bench run` into {args.dir} moves them to {DISCARDED_FILE}", file=sys.stderr)
    tables = summarize(records)
    title = f"steer-bench {manifest.get('suite')}: {len(records)} trials in {args.dir}"
    print(render(tables, args.format, title=title), end="")
    if plots_dir is not None:
        from steer_envs.bench.plots import write_plots

        problems: list[str] = []
        for path in write_plots(records, plots_dir, problems=problems):
            print(f"wrote {path}", file=sys.stderr)
        for problem in problems:
            print(f"warning: {problem}", file=sys.stderr)
        if problems:
            return EXIT_FAILED
    return EXIT_OK


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``steer-bench`` console script; returns the exit status.

    Errors in the request (unknown suite, env, method or parameter, a bad
    value) print one line to stderr and return 2.

    >>> import contextlib, io, tempfile
    >>> with tempfile.TemporaryDirectory() as out, contextlib.redirect_stderr(io.StringIO()) as err:
    ...     status = main(["run", "selftest", "--param", "samples=0", "--out", out, "--no-progress"])
    >>> status, err.getvalue().strip()
    (2, "steer-bench: error: selftest: parameter 'samples' must be >= 1, got 0")
    """
    if argv is not None and (isinstance(argv, (str, bytes)) or not all(isinstance(a, str) for a in argv)):
        raise TypeError(f"argv must be a list of strs, got {argv!r}")
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        if args.command == "list":
            return cmd_list(args)
        if args.command == "run":
            return cmd_run(args, argv)
        return cmd_report(args)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except (
        KeyError,
        ValueError,
        TypeError,
        ImportError,
        OSError,
        StoreLockedError,
        ExecutorStartError,
    ) as exc:
        if os.environ.get("STEER_BENCH_DEBUG"):
            raise
        print(f"steer-bench: error: {_one_line(_message(exc))}", file=sys.stderr)
        return EXIT_USAGE


def _message(exc: BaseException) -> str:
    """The user-facing text of an error (a ``KeyError``'s own message, an ``OSError``'s reason and file)."""
    if isinstance(exc, KeyError) and exc.args:
        return str(exc.args[0])
    if isinstance(exc, OSError) and exc.strerror:
        where = f": {exc.filename}" if exc.filename else ""
        return f"{exc.strerror}{where}"
    return str(exc) or type(exc).__name__


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
