"""What ``pip install steer-envs`` installs: the package list, the extras, and the bare install in a clean venv.

Fast checks read ``setup.cfg``: every package folder is in the wheel, ``[all]``
is every feature extra, the bare ``install_requires`` holds nothing heavy.

The ``packaging`` tests build the wheel from a copy of the checkout: its layout
(``wrappers/`` and ``baselines/`` install as ``steer_envs.wrappers`` /
``steer_envs.baselines``), then ``pip install <wheel>`` with no extras into a
fresh venv, resolved for real (only torch is pinned, to this machine's CPU
wheel: the registry's torch is a multi-GB CUDA build). There, numpy 2 must
resolve, every 2D env is made and stepped, every library module that needs no
extra imports, the LTL translator, two wrappers, a shipped policy and
``steer-bench`` run, and each arm env raises the ``ImportError`` naming
``pip install "steer-envs[arm]"``. pip's cache makes reruns faster (about a
minute; the first run downloads the packages).
"""

from __future__ import annotations

import configparser
import json
import os
import re
import shutil
import subprocess
import sys
import time
import venv
import zipfile
from pathlib import Path

import pytest

from steer_envs.core.extras import EXTRAS, NOT_IN_ALL

ROOT = Path(__file__).resolve().parents[1]
#: source folder -> installed package name (setup.cfg's package_dir)
SOURCE_PACKAGES = {"steer_envs": "steer_envs", "wrappers": "steer_envs.wrappers", "baselines": "steer_envs.baselines"}
#: distributions that only an extra may bring (the bare install must not)
HEAVY = (
    "robosuite",
    "mink",
    "stable-baselines3",
    "ray",
    "minari",
    "fastapi",
    "uvicorn",
    "onnx",
    "onnxruntime",
    "openvino",
    "pygame",
    "selenium",
)
#: library modules that need an extra to import (everything else must import in the bare install)
NEEDS_EXTRA = {
    "steer_envs.ui.server": "ui",  # FastAPI at import
    "steer_envs.ui.browser": "ui",  # the server, to drive it in a browser
}
#: modules that run a command-line program when imported
CLI_MODULES = ("steer_envs.bench.__main__", "steer_envs.ui.__main__", "steer_envs.baselines.training.__main__")


def _setup_cfg() -> configparser.ConfigParser:
    cfg = configparser.ConfigParser()
    cfg.read(ROOT / "setup.cfg", encoding="utf-8")
    return cfg


def _lines(value: str) -> list[str]:
    return [line.strip() for line in value.splitlines() if line.strip() and not line.strip().startswith("#")]


def _name(requirement: str) -> str:
    """The normalized distribution name of a requirement line (``"minari[hdf5]>=0.5"`` -> ``"minari"``)."""
    match = re.match(r"[A-Za-z0-9._-]+", requirement)
    assert match, requirement
    return re.sub(r"[-_.]+", "-", match.group(0)).lower()


def _extras() -> dict[str, list[str]]:
    section = _setup_cfg()["options.extras_require"]
    return {extra: _lines(section[extra]) for extra in section}


# ------------------------------------------------------------------------------------------ setup.cfg


def test_every_package_folder_is_listed() -> None:
    """A new package (a folder with ``__init__.py``) left out of ``packages`` would be missing from the wheel."""
    options = _setup_cfg()["options"]
    listed = set(_lines(options["packages"]))
    mapped = {k.strip(): v.strip() for k, v in (line.split("=") for line in _lines(options["package_dir"]))}
    assert mapped == {v: k for k, v in SOURCE_PACKAGES.items() if k != "steer_envs"}
    found = set()
    for folder, package in SOURCE_PACKAGES.items():
        for init in (ROOT / folder).rglob("__init__.py"):
            rel = init.parent.relative_to(ROOT / folder).parts
            found.add(".".join([package, *rel]))
    assert found - listed == set(), f"add these packages to setup.cfg [options] packages: {sorted(found - listed)}"
    assert listed - found == set(), f"setup.cfg lists packages that do not exist: {sorted(listed - found)}"


def test_all_is_every_feature_extra() -> None:
    extras = _extras()
    assert set(extras) == {*EXTRAS, "all", "dev", "docs"}, "steer_envs.core.extras.EXTRAS lists the feature extras"
    union = {req for extra in EXTRAS if extra not in NOT_IN_ALL for req in extras[extra]}
    assert set(extras["all"]) == union


def test_bare_install_is_light_and_allows_numpy_2() -> None:
    requires = _lines(_setup_cfg()["options"]["install_requires"])
    names = {_name(r) for r in requires}
    assert not names & set(HEAVY), f"only extras may bring {sorted(names & set(HEAVY))}"
    (numpy,) = [r for r in requires if _name(r) == "numpy"]
    assert "<2" not in numpy.replace(" ", ""), numpy
    for extra, requirements in _extras().items():
        # an extra repeats a bare requirement only to narrow it: [arm] caps mujoco for robosuite
        allowed = {"mujoco"} if extra in ("arm", "all") else set()
        assert not {_name(r) for r in requirements} & names - allowed, f"[{extra}] repeats a bare requirement"


def test_the_readme_commands_install_everything() -> None:
    """scripts/quick.sh and scripts/test.sh go through bootstrap.sh: it installs every extra, pinned."""
    bootstrap = (ROOT / "scripts" / "bootstrap.sh").read_text()
    assert '-c requirements/constraints.txt -e ".[all,dev,docs]"' in bootstrap
    assert '".[all,dev,docs]"' in (ROOT / "scripts" / "lock.sh").read_text()
    for script in ("quick.sh", "test.sh"):
        assert "scripts/bootstrap.sh" in (ROOT / "scripts" / script).read_text()
    pinned = {_name(line.split("==")[0]) for line in _lines((ROOT / "requirements" / "constraints.txt").read_text())}
    extras = _extras()
    main = [r for name, reqs in extras.items() if name not in NOT_IN_ALL for r in reqs]
    wanted = _lines(_setup_cfg()["options"]["install_requires"]) + main
    assert {_name(r) for r in wanted} - pinned == set(), "requirements/constraints.txt must pin every requirement"
    # the extras `all` leaves out are pinned in the interop environment's lock (scripts/test_interop.sh)
    interop = {_name(line.split("==")[0]) for line in _lines((ROOT / "requirements" / "interop.txt").read_text())}
    apart = {_name(r) for name in NOT_IN_ALL for r in extras[name]}
    assert apart - interop == set(), "requirements/interop.txt must pin the extras `all` leaves out"


# ------------------------------------------------------------------------------------------ the wheel


def _copy_checkout(dst: Path) -> None:
    """Copy the files git would ship (tracked + untracked, minus ignored)."""
    files = subprocess.run(
        ["git", "ls-files", "-co", "--exclude-standard", "-z"], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout.split("\0")
    for rel in filter(None, files):
        src = ROOT / rel
        if src.is_file():
            (dst / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dst / rel)


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    tmp = tmp_path_factory.mktemp("wheel")
    _copy_checkout(tmp / "src")
    pip_wheel = [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q"]
    subprocess.run([*pip_wheel, "-w", str(tmp / "dist"), str(tmp / "src")], check=True, capture_output=True)
    (path,) = (tmp / "dist").glob("steer_envs-*.whl")
    return path


@pytest.mark.packaging
def test_wheel_installs_subpackages_under_steer_envs(wheel: Path) -> None:
    names = zipfile.ZipFile(wheel).namelist()
    top_level = {n.split("/")[0] for n in names}
    assert "wrappers" not in top_level and "baselines" not in top_level, top_level
    for module in ("wrappers/__init__.py", "baselines/__init__.py", "core/task.py", "core/extras.py", "py.typed"):
        assert f"steer_envs/{module}" in names
    assert "steer_envs/baselines/checkpoints/maze2d_large/dp.safetensors" in names
    metadata = zipfile.ZipFile(wheel).read(next(n for n in names if n.endswith(".dist-info/METADATA"))).decode()
    assert {m for m in re.findall(r"^Provides-Extra: (\S+)$", metadata, re.M)} == {*EXTRAS, "all", "dev", "docs"}


def _cpu_torch_pin() -> str:
    """This interpreter's torch as the CPU build (``torch==2.13.0+cpu``): pip finds only the local CPU wheel."""
    import torch

    return f"torch=={torch.__version__.split('+')[0]}+cpu"


#: run in the bare venv, from a neutral folder; prints one JSON line
BARE_CHECK = r"""
import importlib, importlib.metadata as md, json, pkgutil, sys, time
start = time.perf_counter()
import numpy as np
import gymnasium as gym
import steer_envs
from steer_envs.envs.registry import ENTRIES

HEAVY, NEEDS_EXTRA, CLI_MODULES = json.loads(sys.argv[1])
report = {"numpy": np.__version__, "python": sys.version.split()[0]}

def installed(dist):
    try:
        return md.version(dist)
    except md.PackageNotFoundError:
        return None

report["heavy"] = {d: v for d in HEAVY if (v := installed(d))}
assert steer_envs.__file__.startswith(sys.prefix), steer_envs.__file__
import importlib.util as u
assert u.find_spec("wrappers") is None and u.find_spec("baselines") is None

# every env: the bare ones make and step, the others name their extra
made, refused = [], []
for e in ENTRIES:
    if e.extra is None:
        env = gym.make(e.id)
        env.reset(seed=0)
        env.action_space.seed(0)
        for _ in range(3):
            env.step(env.action_space.sample())
        env.close()
        made.append(e.id)
    else:
        try:
            gym.make(e.id)
        except ImportError as exc:
            command = f'pip install "steer-envs[{e.extra}]"'
            assert command in str(exc), (e.id, str(exc))
            refused.append(e.id)
        else:
            raise AssertionError(f"{e.id} was made without its extra {e.extra!r}")
report["made"], report["refused"] = made, refused

# LTL: parse, translate, accept
from steer_envs.ltl import parse, translate
automaton = translate(parse("G(request -> F grant)"))
assert automaton.accepts(prefix=[{"request"}], loop=[{"grant"}])
assert not automaton.accepts(prefix=[], loop=[{"request"}])

# wrappers around a 2D env
from steer_envs.wrappers import DSModulationWrapper, LTLReplanWrapper
env = DSModulationWrapper(LTLReplanWrapper(gym.make("steer_envs/SoupScoop-v0")), attractor=[4.75, 5.99])
env.reset(seed=0)
for _ in range(3):
    env.step(env.action_space.sample())
assert [w.name for w in env.spec.additional_wrappers] == ["LTLReplanWrapper", "DSModulationWrapper"]

# a shipped policy plans in the maze
from steer_envs.baselines.pretrained import load_pretrained
policy = load_pretrained("dp")
obs, _ = gym.make("steer_envs/Maze2D-Large-v0").reset(seed=0)
plans = policy.sample(obs, 2, generator=np.random.default_rng(0))
assert plans.shape[0] == 2 and np.isfinite(plans).all(), plans.shape

# every library module that needs no extra imports
skip = tuple(CLI_MODULES)
failed = {}
for root in ("steer_envs", "steer_envs.wrappers", "steer_envs.baselines"):
    package = importlib.import_module(root)
    for info in pkgutil.walk_packages(package.__path__, prefix=root + "."):
        if info.name.startswith(skip) or info.name in NEEDS_EXTRA:
            continue
        try:
            importlib.import_module(info.name)
        except Exception as exc:
            failed[info.name] = f"{type(exc).__name__}: {exc}"
assert not failed, failed
for name, extra in NEEDS_EXTRA.items():
    try:
        importlib.import_module(name)
    except ImportError:
        pass
    else:
        raise AssertionError(f"{name} imported without the {extra!r} extra: drop it from NEEDS_EXTRA")
# steer-bench (its console script's main) lists every suite and runs one that needs no extra
import contextlib, io, os
from steer_envs.bench.cli import main
listing = io.StringIO()
with contextlib.redirect_stdout(listing):
    assert main(["list"]) == 0
assert "selftest" in listing.getvalue() and "itps" in listing.getvalue()
with contextlib.redirect_stdout(io.StringIO()):
    assert main(["run", "selftest", "--seeds", "1", "--out", "bench", "--no-progress"]) == 0
assert os.path.isfile("bench/summary.md")
report["seconds"] = round(time.perf_counter() - start, 1)
print(json.dumps(report))
"""


@pytest.mark.packaging
def test_bare_install_in_a_clean_venv(wheel: Path, tmp_path: Path) -> None:
    """``pip install <wheel>`` (no extras) resolves with numpy 2; the 2D envs, LTL, wrappers, policies, bench work."""
    env_dir = tmp_path / "venv"
    venv.EnvBuilder(with_pip=False).create(env_dir)
    py = env_dir / "bin" / "python"
    constraints = tmp_path / "torch-cpu.txt"
    constraints.write_text(_cpu_torch_pin() + "\n")
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}
    env |= {"PIP_DISABLE_PIP_VERSION_CHECK": "1", "MUJOCO_GL": os.environ.get("MUJOCO_GL", "osmesa")}
    start = time.perf_counter()
    pip_install = [sys.executable, "-m", "pip", "--python", str(py), "install", "-q", "--no-compile"]
    install = subprocess.run(
        [*pip_install, "-c", str(constraints), str(wheel)],
        capture_output=True,
        text=True,
        env=env,
        timeout=900,
    )
    assert install.returncode == 0, install.stdout[-3000:] + install.stderr[-3000:]
    install_s = time.perf_counter() - start

    args = json.dumps([HEAVY, NEEDS_EXTRA, CLI_MODULES])
    check = subprocess.run(
        [str(py), "-c", BARE_CHECK, args], capture_output=True, text=True, cwd=tmp_path, env=env, timeout=600
    )
    assert check.returncode == 0, check.stdout[-3000:] + check.stderr[-5000:]
    report = json.loads(check.stdout.strip().splitlines()[-1])
    assert int(report["numpy"].split(".")[0]) >= 2, report["numpy"]
    assert report["heavy"] == {}, f"the bare install brought {report['heavy']}"
    from steer_envs.envs.registry import ENTRIES

    assert report["made"] == [e.id for e in ENTRIES if e.extra is None]
    assert report["refused"] == [e.id for e in ENTRIES if e.extra is not None]
    assert any("Maze2D" in i for i in report["made"]) and any("PolygonNav" in i for i in report["made"])

    for script in ("steer-bench", "steer-ui"):
        assert (env_dir / "bin" / script).is_file(), script
    print(f"bare install: numpy {report['numpy']}, pip {install_s:.0f} s, checks {report['seconds']} s")
