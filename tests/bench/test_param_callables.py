"""Suite parameters name data, not code: a loader parameter takes a registered loader, not any import.

``--param loader=os:system`` is refused (exit 2, naming the parameter and the
registered choices) before anything is imported; ``--allow-import`` lets any
``module:function`` through and says so on stderr. Registered names stand for
their paths (equal configs hash equally); a plugin can register its own.
"""

from __future__ import annotations

import copy
import os
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import pytest
from bench_helpers import bench_env

from steer_envs.bench.cli import main
from steer_envs.bench.params import PolicyLoader, SuiteParams, check_callable_params
from steer_envs.bench.suite import Trial, get_suite, suites
from steer_envs.utils import imports
from steer_envs.utils.imports import POLICY_LOADER, named_callable, register_callable, registered_callables

PRETRAINED = "steer_envs.baselines.pretrained:load_pretrained"
#: suite -> its parameters that name a policy loader
LOADER_PARAMS = {
    "itps-maze2d": ("dp_loader", "act_loader"),
    "itps-kitchen": ("loader",),
    "itps-blockstack": ("loader",),
}


@pytest.fixture
def registry(monkeypatch: pytest.MonkeyPatch) -> dict[str, dict[str, str]]:
    """A private copy of the registry of named callables (registrations in a test do not leak)."""
    private = copy.deepcopy(imports._REGISTERED)
    monkeypatch.setattr(imports, "_REGISTERED", private)
    return private


def _marker_loader(folder: Path, name: str) -> Path:
    """A module ``name`` in ``folder`` that writes ``<name>.ran`` when imported and when its ``load`` is called.

    ``load`` then raises FileNotFoundError, which the suites read as "the policy is not available".
    """
    marker = folder / f"{name}.ran"
    (folder / f"{name}.py").write_text(
        "from pathlib import Path\n"
        f"MARKER = Path({str(marker)!r})\n"
        "MARKER.write_text('imported\\n')\n"
        "def load(kind):\n"
        "    with MARKER.open('a') as f:\n"
        "        f.write(f'called {kind}\\n')\n"
        "    raise FileNotFoundError(f'no {kind} policy here')\n"
    )
    return marker


# ----------------------------------------------------------------------------- the registry
def test_a_registered_name_or_its_path_is_accepted_anything_else_refused() -> None:
    assert registered_callables(POLICY_LOADER)["pretrained"] == PRETRAINED
    assert named_callable("pretrained", POLICY_LOADER, what="loader") == PRETRAINED
    assert named_callable(PRETRAINED, POLICY_LOADER, what="loader") == PRETRAINED
    for code in ("os:system", "builtins:print", "steer_envs.bench.cli:os.system", "steer_envs.no_such_module:load"):
        with pytest.raises(ValueError, match=rf"loader names code: '{re.escape(code)}' is not a registered") as err:
            named_callable(code, POLICY_LOADER, what="loader")
        assert "pretrained (steer_envs.baselines.pretrained:load_pretrained)" in str(err.value)
        assert named_callable(code, POLICY_LOADER, what="loader", allow_import=True) == code
    for junk in ("", "pretraind", "os:", ":system", "a b:c", "os:system; rm"):
        with pytest.raises(ValueError, match="must name a registered policy loader"):
            named_callable(junk, POLICY_LOADER, what="loader", allow_import=True)
    with pytest.raises(TypeError, match="loader must be a str"):
        named_callable(3, POLICY_LOADER, what="loader")  # type: ignore[arg-type]


def test_register_callable_checks_its_arguments(registry: dict[str, dict[str, str]]) -> None:
    register_callable(POLICY_LOADER, "my-policy", "my_plugin.loaders:load")
    register_callable(POLICY_LOADER, "my-policy", "my_plugin.loaders:load")  # the same again: nothing changes
    assert registered_callables(POLICY_LOADER)["my-policy"] == "my_plugin.loaders:load"
    with pytest.raises(ValueError, match="already registered"):
        register_callable(POLICY_LOADER, "my-policy", "other:load")
    with pytest.raises(ValueError, match="`name` must be"):
        register_callable(POLICY_LOADER, "os:system", "os:system")
    with pytest.raises(ValueError, match="`path` must be 'module:qualname'"):
        register_callable(POLICY_LOADER, "mine", "my_plugin.loaders")
    with pytest.raises(TypeError, match="`kind` must be a non-empty str"):
        register_callable("", "mine", "my_plugin.loaders:load")
    registered_callables(POLICY_LOADER).clear()  # a copy
    assert "my-policy" in registered_callables(POLICY_LOADER)


# ----------------------------------------------------------------------------- suite parameters
def test_every_parameter_that_names_code_is_typed_so() -> None:
    """A suite default that reads as ``module:function`` must be a NamesCallable parameter (checked on the CLI)."""
    path = re.compile(r"[A-Za-z_][\w.]*:[A-Za-z_][\w.]*")
    for suite in suites():
        kinds = type(suite.defaults).callable_params()
        looks_like_code = {k for k, v in suite.defaults.to_json().items() if isinstance(v, str) and path.fullmatch(v)}
        assert looks_like_code <= set(kinds), f"{suite.name}: {sorted(looks_like_code - set(kinds))} untyped"
        assert set(kinds) == set(LOADER_PARAMS.get(suite.name, ())), suite.name


@pytest.mark.parametrize(("suite_name", "param"), [(s, p) for s, ps in LOADER_PARAMS.items() for p in ps])
def test_a_loader_name_stands_for_its_path(suite_name: str, param: str) -> None:
    suite = get_suite(suite_name)
    by_name = suite.resolve_params({param: "pretrained"})
    assert getattr(by_name, param) == PRETRAINED
    assert by_name.to_json() == suite.defaults.to_json()  # same config, same trial keys as the default
    key = Trial(suite.name, None, "m", 0, by_name.to_json(), "math:sqrt").key
    assert key == Trial(suite.name, None, "m", 0, suite.defaults.to_json(), "math:sqrt").key
    with pytest.raises(ValueError, match=rf"parameter '{param}' must be a registered policy loader"):
        suite.resolve_params({param: "pretraind"})


@pytest.mark.parametrize("value", ["os:system", "builtins:print"])
def test_check_callable_params_refuses_code_naming_suite_and_parameter(value: str) -> None:
    params_type = type(get_suite("itps-kitchen").defaults)
    with pytest.raises(ValueError, match=rf"suite 'itps-kitchen': parameter 'loader' names code: '{value}'") as err:
        check_callable_params(params_type, {"loader": value}, suite="itps-kitchen", allow_import=False)
    assert "registered: pretrained" in str(err.value) and "--allow-import" in str(err.value)
    allowed = check_callable_params(params_type, {"loader": value, "batch": 2}, suite="itps-kitchen", allow_import=True)
    assert allowed == {"loader": value}
    for given in ({"loader": "pretrained"}, {"loader": PRETRAINED}, {"loader": 7}, {"batch": 2}):
        assert check_callable_params(params_type, given, suite="itps-kitchen", allow_import=False) == {}


@dataclass(frozen=True)
class PluginParams(SuiteParams):
    """A plugin suite's parameters with a loader."""

    suite_name: ClassVar[str] = "mine"
    loader: PolicyLoader = PRETRAINED


def test_a_plugin_registered_loader_passes_without_allow_import(registry: dict[str, dict[str, str]]) -> None:
    with pytest.raises(ValueError, match="is not a registered policy loader"):
        check_callable_params(PluginParams, {"loader": "my_plugin:load"}, suite="mine", allow_import=False)
    register_callable(POLICY_LOADER, "mine", "my_plugin:load")
    for value in ("mine", "my_plugin:load"):
        assert check_callable_params(PluginParams, {"loader": value}, suite="mine", allow_import=False) == {}
    assert PluginParams.from_json({"loader": "mine"}).loader == "my_plugin:load"


# ----------------------------------------------------------------------------- the command line
def test_cli_refuses_a_loader_that_names_code_before_importing_it(tmp_path: Path) -> None:
    marker = _marker_loader(tmp_path, "marker_refused")
    argv = ["run", "itps-kitchen", "--param", "loader=marker_refused:load", "--seeds", "1", "--no-progress"]
    env = bench_env()
    env["PYTHONPATH"] = os.pathsep.join([str(tmp_path), env["PYTHONPATH"]])
    command = [sys.executable, "-m", "steer_envs.bench", *argv, "--out", str(tmp_path / "out")]
    done = subprocess.run(command, capture_output=True, text=True, timeout=300, env=env)
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in done.stderr, done.stderr
    assert lines[0].startswith("steer-bench: error: suite 'itps-kitchen': parameter 'loader' names code")
    assert "registered: pretrained" in lines[0] and "--allow-import" in lines[0]
    assert not marker.exists()  # neither imported nor called


@pytest.mark.parametrize("value", ["os:system", "builtins:print"])
def test_cli_refuses_any_callable_outside_the_registry(value: str, tmp_path: Path, capsys) -> None:
    status = main(["run", "itps-kitchen", "--param", f"loader={value}", "--out", str(tmp_path), "--no-progress"])
    captured = capsys.readouterr()
    assert status == 2
    assert captured.out == ""  # builtins:print was not called
    assert f"parameter 'loader' names code: '{value}'" in captured.err and "pretrained" in captured.err
    assert not (tmp_path / "results.jsonl").exists()


def test_cli_allow_import_runs_the_named_code_and_says_so(
    tmp_path: Path, capsys, monkeypatch: pytest.MonkeyPatch
) -> None:
    marker = _marker_loader(tmp_path, "marker_allowed")
    monkeypatch.syspath_prepend(str(tmp_path))
    argv = ["run", "itps-kitchen", "--param", "loader=marker_allowed:load", "--allow-import", "--seeds", "1"]
    status = main([*argv, "--out", str(tmp_path / "out"), "--no-progress"])
    err = capsys.readouterr().err
    assert status == 0, err
    assert "warning: --allow-import imports and runs arbitrary code: loader=marker_allowed:load" in err
    assert marker.read_text().splitlines() == ["imported", "called kitchen"]


def test_cli_takes_a_registered_loader_by_name(tmp_path: Path, capsys) -> None:
    argv = ["run", "itps-kitchen", "--param", "loader=pretrained", "--param", "batch=0", "--out", str(tmp_path)]
    assert main([*argv, "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "'batch' must be" in err and "loader" not in err  # the loader passed; the batch check stopped the run
