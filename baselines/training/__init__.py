"""One training entry point for every trajectory policy and dataset (``python -m steer_envs.baselines.training``).

Usage errors exit with status 2 (after printing the usage to stderr):

>>> import contextlib, io
>>> with contextlib.redirect_stderr(io.StringIO()):
...     main(["--policy", "dp", "--dataset", "missing.npz", "--out", "x.safetensors"])
Traceback (most recent call last):
...
SystemExit: 2
"""

from steer_envs.baselines.common.configuration import TrainSettings
from steer_envs.baselines.training.cli import main, parse_overrides
from steer_envs.baselines.training.trainer import check_record, read_record, snapshot_run, train_policy

__all__ = ["TrainSettings", "check_record", "main", "parse_overrides", "read_record", "snapshot_run", "train_policy"]
