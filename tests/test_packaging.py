"""The wheel installs ``wrappers/`` and ``baselines/`` as ``steer_envs.wrappers``/``steer_envs.baselines``.

Builds a wheel from a copy of the checkout, installs it (without dependencies)
into a fresh virtual environment whose dependencies come from the running
interpreter, and imports it from a neutral directory.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import sysconfig
import venv
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.packaging


def _copy_checkout(dst: Path) -> None:
    """Copy the files git would ship (tracked + untracked, minus ignored)."""
    files = subprocess.run(
        ["git", "ls-files", "-co", "--exclude-standard"], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout.split()
    for rel in files:
        src = ROOT / rel
        if src.is_file():
            (dst / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dst / rel)


def test_wheel_installs_subpackages_under_steer_envs(tmp_path: Path) -> None:
    src = tmp_path / "src"
    _copy_checkout(src)
    dist = tmp_path / "dist"
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w", str(dist), str(src)],
        check=True,
    )
    (wheel,) = dist.glob("steer_envs-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    top_level = {n.split("/")[0] for n in names}
    assert "wrappers" not in top_level and "baselines" not in top_level, top_level
    assert "steer_envs/wrappers/__init__.py" in names
    assert "steer_envs/baselines/__init__.py" in names
    assert "steer_envs/core/task.py" in names

    env_dir = tmp_path / "venv"
    venv.EnvBuilder(with_pip=False).create(env_dir)
    py = env_dir / "bin" / "python"
    subprocess.run(
        [sys.executable, "-m", "pip", "--python", str(py), "install", "--no-deps", "-q", str(wheel)], check=True
    )
    # dependencies come from the running interpreter's site-packages (appended after the venv's own)
    site = Path(
        subprocess.run(
            [py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    )
    (site / "_deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    code = (
        "import steer_envs, steer_envs.wrappers, steer_envs.baselines, gymnasium as gym\n"
        f"assert steer_envs.__file__.startswith(r'{site}'), steer_envs.__file__\n"
        f"assert steer_envs.wrappers.__file__.startswith(r'{site}'), steer_envs.wrappers.__file__\n"
        "assert 'steer_envs/PolygonNav-4Mode-v0' in gym.registry\n"
        "import importlib.util as u; assert u.find_spec('wrappers') is None and u.find_spec('baselines') is None\n"
    )
    subprocess.run([py, "-c", code], check=True, cwd=tmp_path)
