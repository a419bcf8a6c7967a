"""A feature used without its extra raises an ``ImportError`` that names ``pip install "steer-envs[<extra>]"``.

Missing packages are simulated with ``sys.modules[name] = None`` (what ``import
name`` then raises is Python's ``ModuleNotFoundError``, as for a package that is
not installed); the clean-venv check of the real bare install is
``tests/test_packaging.py``.
"""

from __future__ import annotations

import pickle
import sys
import types

import gymnasium as gym
import pytest
from gymnasium.error import DependencyNotInstalled

import steer_envs  # noqa: F401  (registers the ids)
from steer_envs.core.extras import EXTRAS, MissingExtraError, install_command, missing_modules, require
from steer_envs.envs.registry import ENTRIES


def test_require_returns_the_module() -> None:
    import json

    assert require("json", "arm", "JSON") is json
    assert require("os.path", "arm", "paths") is sys.modules["os.path"]


@pytest.mark.parametrize("extra", EXTRAS)
def test_missing_module_names_the_extra(extra: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "steer_fake_pkg", None)
    with pytest.raises(MissingExtraError) as info:
        require("steer_fake_pkg", extra, "the feature")
    err = info.value
    assert str(err) == f'the feature needs steer-fake-pkg, which is not installed: pip install "steer-envs[{extra}]"'
    assert err.extra == extra and err.name == "steer_fake_pkg"
    # an ImportError (and Gymnasium's DependencyNotInstalled), chained to the original error
    assert isinstance(err, ImportError) and isinstance(err, ModuleNotFoundError)
    assert isinstance(err, DependencyNotInstalled)
    assert isinstance(err.__cause__, ModuleNotFoundError)
    copy = pickle.loads(pickle.dumps(err))  # process-pool workers send errors back pickled
    assert (type(copy), str(copy), copy.name, copy.extra) == (MissingExtraError, str(err), err.name, err.extra)


def test_submodule_and_distribution_name(monkeypatch: pytest.MonkeyPatch) -> None:
    # the submodule too: another test may have imported it already, and a cached submodule skips its parent
    for name in ("stable_baselines3", "stable_baselines3.common", "stable_baselines3.common.monitor"):
        monkeypatch.setitem(sys.modules, name, None)
    with pytest.raises(ImportError, match=r'sb3 needs stable-baselines3, which is not installed: .*\[rl\]"$'):
        require("stable_baselines3.common.monitor", "rl", "sb3")
    with pytest.raises(ImportError, match=r"^UI needs the web stack, which is not installed"):
        require("stable_baselines3", "ui", "UI", package="the web stack")


def test_installed_package_with_a_missing_dependency(monkeypatch: pytest.MonkeyPatch) -> None:
    """The package is there but its import fails on a missing module: the message says both."""
    fake = types.ModuleType("steer_fake_parent")
    fake.__path__ = []  # a package whose submodule imports a missing module
    monkeypatch.setitem(sys.modules, "steer_fake_parent", fake)
    monkeypatch.setitem(sys.modules, "steer_fake_dep", None)

    class _Finder:
        def find_spec(self, name: str, path: object = None, target: object = None) -> None:
            if name == "steer_fake_parent.child":
                import steer_fake_dep  # noqa: F401
            return None

    monkeypatch.setattr(sys, "meta_path", [_Finder(), *sys.meta_path])
    with pytest.raises(MissingExtraError, match=r"whose import failed .*steer_fake_dep.*\[arm\]\" installs it"):
        require("steer_fake_parent.child", "arm", "X")


def test_other_import_errors_pass_through(monkeypatch: pytest.MonkeyPatch) -> None:
    class _Broken:
        def find_spec(self, name: str, path: object = None, target: object = None) -> None:
            if name == "steer_fake_broken":
                raise ImportError("DLL load failed")
            return None

    monkeypatch.setattr(sys, "meta_path", [_Broken(), *sys.meta_path])
    with pytest.raises(ImportError, match="DLL load failed") as info:
        require("steer_fake_broken", "arm", "X")
    assert not isinstance(info.value, MissingExtraError)


def test_install_command_and_unknown_extra() -> None:
    assert install_command("all") == 'pip install "steer-envs[all]"'
    with pytest.raises(ValueError, match="unknown steer-envs extra 'robosuite'"):
        install_command("robosuite")
    with pytest.raises(ValueError, match="unknown steer-envs extra"):
        require("json", "robosuite", "X")


def test_missing_modules(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "steer_fake_pkg", None)
    assert missing_modules("json", "steer_fake_pkg", "steer_fake_absent.sub") == [
        "steer_fake_pkg",
        "steer_fake_absent.sub",
    ]


def test_registry_extras_are_known() -> None:
    assert {e.extra for e in ENTRIES} <= {None, *EXTRAS}
    arm = {e.name for e in ENTRIES if e.extra == "arm"}
    assert arm == {"Lift-v0", "Can-v0", "Square-v0", "BlockStack-v0", "ArmScoop-v0", "Kitchen-v0"}
    assert all(e.entry_point.startswith("steer_envs.envs.robosuite.") == (e.extra == "arm") for e in ENTRIES)


@pytest.mark.parametrize("name", ["Lift-v0", "Can-v0", "Square-v0", "BlockStack-v0", "ArmScoop-v0", "Kitchen-v0"])
def test_arm_env_without_robosuite_names_the_arm_extra(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    for module in [m for m in sys.modules if m == "robosuite" or m.startswith("robosuite.")]:
        monkeypatch.delitem(sys.modules, module)
    monkeypatch.setitem(sys.modules, "robosuite", None)
    with pytest.raises(
        ImportError, match=r'^the robosuite arm envs .* needs robosuite, .*: pip install "steer-envs\[arm\]"$'
    ):
        gym.make(f"steer_envs/{name}")


def test_ray_executor_without_ray(monkeypatch: pytest.MonkeyPatch) -> None:
    from steer_envs.bench.executors import import_ray

    monkeypatch.setitem(sys.modules, "ray", None)
    with pytest.raises(MissingExtraError, match=r'the Ray executor needs ray, .*"steer-envs\[ray\]"'):
        import_ray()


def test_steer_ui_without_the_web_stack(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    from steer_envs.ui.cli import main

    monkeypatch.setitem(sys.modules, "fastapi", None)
    assert main([]) == 2
    assert 'steer-ui needs fastapi, which is not installed: pip install "steer-envs[ui]"' in capsys.readouterr().err


def test_sb3_training_without_stable_baselines3(monkeypatch: pytest.MonkeyPatch) -> None:
    from steer_envs.baselines.sb3 import Sb3Settings, make_env, train_and_evaluate

    monkeypatch.setitem(sys.modules, "stable_baselines3", None)
    pattern = r'^training stable-baselines3 agents .* needs stable-baselines3, .*: pip install "steer-envs\[rl\]"$'
    with pytest.raises(MissingExtraError, match=pattern):
        make_env("steer_envs/Maze2D-UmazeDense-v0", "sac", Sb3Settings(timesteps=100))
    with pytest.raises(MissingExtraError, match=pattern):
        train_and_evaluate("steer_envs/Maze2D-UmazeDense-v0", "sac", 0, Sb3Settings(timesteps=100))


def test_to_minari_without_minari(monkeypatch: pytest.MonkeyPatch) -> None:
    from steer_envs.data import maze_random_walk as walk

    monkeypatch.setitem(sys.modules, "minari", None)
    monkeypatch.setattr(walk, "goal_episodes", lambda dataset: [object()])
    dataset = object.__new__(walk.RandomWalkDataset)
    with pytest.raises(MissingExtraError, match=r'^to_minari needs minari, .*: pip install "steer-envs\[minari\]"$'):
        walk.to_minari(dataset, "steer/walk-v0")
