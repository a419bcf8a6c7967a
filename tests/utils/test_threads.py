"""Thread limits: limit_threads restores, set_process_threads / --threads for scripts."""

from __future__ import annotations

import argparse

import pytest
import torch
from threadpoolctl import threadpool_info

from steer_envs.utils.threads import add_threads_argument, limit_threads, set_process_threads, single_threaded


def test_limit_threads_caps_and_restores() -> None:
    before = torch.get_num_threads()
    with single_threaded():
        assert torch.get_num_threads() == 1
        assert all(pool["num_threads"] == 1 for pool in threadpool_info())
    assert torch.get_num_threads() == before
    with pytest.raises(ValueError, match="torch_threads"):
        with limit_threads(torch_threads=0):
            pass


def test_set_process_threads_lasts_and_is_checked() -> None:
    before = torch.get_num_threads()
    try:
        set_process_threads(1)
        assert torch.get_num_threads() == 1
        assert all(pool["num_threads"] == 1 for pool in threadpool_info())
    finally:
        set_process_threads(before)
    for bad in (0, -1, True, 1.5, "2"):
        with pytest.raises(ValueError, match="threads"):
            set_process_threads(bad)  # type: ignore[arg-type]


def test_threads_argument_defaults_to_one_and_refuses_bad_values(capsys: pytest.CaptureFixture[str]) -> None:
    parser = argparse.ArgumentParser(prog="demo")
    add_threads_argument(parser)
    assert parser.parse_args([]).threads == 1
    assert parser.parse_args(["--threads", "4"]).threads == 4
    for bad in ("0", "x", "100000"):
        with pytest.raises(SystemExit):
            parser.parse_args(["--threads", bad])
        assert "--threads" in capsys.readouterr().err
    with pytest.raises(ValueError, match="default"):
        add_threads_argument(argparse.ArgumentParser(), default=0)


def test_the_blas_limit_does_not_override_torchs_threads() -> None:
    """threadpoolctl's OpenMP limit also sets torch's threads: the torch setting must win either way."""
    import torch

    from steer_envs.utils.threads import limit_threads

    before = torch.get_num_threads()
    with limit_threads(blas_threads=2, torch_threads=1):
        assert torch.get_num_threads() == 1
    with limit_threads(blas_threads=1, torch_threads=2):
        assert torch.get_num_threads() == 2
    assert torch.get_num_threads() == before
