"""One loader for every shipped checkpoint, a file in a shipped one's place, any checkpoint file; one cache."""

from __future__ import annotations

from pathlib import Path

import pytest

torch = pytest.importorskip("torch")

from steer_envs.baselines.pretrained import (  # noqa: E402
    CHECKPOINTS,
    POLICY_UNAVAILABLE,
    PRETRAINED_LOADER,
    checkpoint_path,
    checkpoint_record,
    load_pretrained,
    resolve_policy,
    shared_policy,
)

LOADER = f"{__name__}:load_test_policy"


def load_test_policy(name: str) -> object:
    return load_pretrained("act")


def load_nothing() -> object:
    return object()


@pytest.mark.parametrize("name", sorted(CHECKPOINTS))
def test_every_shipped_checkpoint_loads_by_name_with_its_record(name: str) -> None:
    policy = load_pretrained(name)
    shipped = CHECKPOINTS[name]
    assert policy.name == shipped.kind and getattr(policy, "interaction_dims", None) == shipped.interaction_dims
    assert checkpoint_record(name)["training"]["final_loss"] > 0  # --check replays this record's loss curve


def test_a_checkpoint_file_takes_a_shipped_ones_place_or_loads_by_its_path(tmp_path: Path) -> None:
    path = checkpoint_path("blockstack")
    kitchen_layout = load_pretrained("kitchen", checkpoint=path)
    assert kitchen_layout.action_dim == 4 and kitchen_layout.interaction_dims == (0, 1, 2)
    by_path = load_pretrained(path)
    assert by_path.config == kitchen_layout.config and getattr(by_path, "interaction_dims", None) is None
    with pytest.raises(ValueError, match="holds a 'dp' policy, expected 'act'"):
        load_pretrained("act", checkpoint=path)
    with pytest.raises(ValueError, match="no checkpoint file"):
        load_pretrained(tmp_path / "absent.safetensors")
    with pytest.raises(ValueError, match="name must be one of"):
        load_pretrained("bc")


def test_a_glide_classifier_file_loads_as_a_classifier(tmp_path: Path) -> None:
    from steer_envs.baselines.glide.classifier import ModeClassifier

    path = ModeClassifier(2, 3, hidden=8).save(tmp_path / "classifier.safetensors")
    assert isinstance(load_pretrained(path), ModeClassifier)


def test_loaders_and_the_per_process_cache() -> None:
    assert resolve_policy(PRETRAINED_LOADER, "act").name == "act"
    assert resolve_policy(LOADER, "dp").name == "act"  # the loader decides, called with the name
    with pytest.raises(TypeError, match="must return a TrajectoryPolicy"):
        resolve_policy(f"{__name__}:load_nothing", "dp")
    with pytest.raises(POLICY_UNAVAILABLE):
        resolve_policy("steer_envs.no_such_module:load", "dp")
    with pytest.raises(POLICY_UNAVAILABLE):
        resolve_policy(f"{__name__}:no_such_function", "dp")
    first = shared_policy("act", loader=LOADER)
    assert shared_policy("act", loader=LOADER) is first and shared_policy("act") is not first
    with pytest.raises(TypeError, match="needs a policy with an accelerate method"):
        shared_policy("act", accelerate="trace", owner="needs")
