"""progress_bar: a bar on a terminal, none in a log unless asked for, none when turned off."""

from __future__ import annotations

import io

import numpy as np
import pytest

from steer_envs.core.progress import check_progress, progress_bar


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def _drawn(enabled: bool | None, file: io.StringIO) -> str:
    bar = progress_bar(range(3), enabled=enabled, file=file, desc="work", mininterval=0)
    assert list(bar) == [0, 1, 2]  # the items come through whether or not a bar is drawn
    return file.getvalue()


def test_auto_draws_on_a_terminal_only() -> None:
    assert "work: 100%" in _drawn(None, _Terminal())
    assert _drawn(None, io.StringIO()) == ""  # a log file, a CI job, a pipe: quiet


def test_true_draws_everywhere_and_false_nowhere() -> None:
    assert "work: 100%" in _drawn(True, io.StringIO())
    assert _drawn(False, _Terminal()) == ""
    assert progress_bar(total=2, enabled=np.bool_(False)).disable


def test_a_hidden_bar_takes_every_call() -> None:
    bar = progress_bar(total=5, enabled=False)
    bar.update(2)
    bar.set_postfix_str("failed=1")
    bar.set_postfix(loss="0.1")
    bar.close()


@pytest.mark.parametrize("value", ["no", 1, 0.0, "auto"])
def test_anything_but_a_bool_or_none_is_refused(value: object) -> None:
    with pytest.raises(TypeError, match=r"my_loop: progress must be True, False or None"):
        check_progress(value, owner="my_loop")
    with pytest.raises(TypeError, match="enabled must be True, False or None"):
        progress_bar(total=1, enabled=value)  # type: ignore[arg-type]
