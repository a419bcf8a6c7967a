"""GLiDE mode classifier: losses, packing, training, the dynamics loss, files, metrics, k-means."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from steer_envs.baselines.glide import (
    ForwardModel,
    GlideLossWeights,
    GlideTrainConfig,
    KMeansSegmentation,
    ModeClassifier,
    glide_losses,
    mode_iou,
    mode_overlap,
    pack_trajectories,
    train_mode_classifier,
    workspace_grid,
)
from steer_envs.core.task import TaskSpec

#: 3-mode chain a -> b -> c with back edges: only a -> c is infeasible.
F3 = TaskSpec.linear("chain", ("a", "b", "c"), back_edges=True).feasibility_matrix()


def _one_hot_logits(modes_per_state: np.ndarray, k: int) -> torch.Tensor:
    return torch.nn.functional.one_hot(torch.as_tensor(modes_per_state), k).float()[None] * 50.0


def _band_modes(x: np.ndarray) -> np.ndarray:
    """Toy ground truth: mode 0 for x < 0, 1 for 0 <= x < 1, 2 for x >= 1."""
    return np.digitize(x[:, 0], [0.0, 1.0])


# ------------------------------------------------------------------------- config
def test_loss_weights_validate_and_ablate() -> None:
    w = GlideLossWeights()
    assert (w.succ, w.fail, w.init, w.final, w.dyn, w.fail_clip) == (1000.0, 1.0, 10.0, 10.0, 0.0, -1.0)
    assert w.without("succ", "fail").succ == 0 and w.without("succ", "fail").init == 10
    with pytest.raises(ValueError, match="unknown loss term"):
        w.without("prediction")
    with pytest.raises(ValueError, match="succ"):
        GlideLossWeights(succ=-1.0)
    with pytest.raises(ValueError, match="fail_clip"):
        GlideLossWeights(fail_clip=0.5)
    with pytest.raises(ValueError, match="epochs"):
        GlideTrainConfig(epochs=0)
    with pytest.raises(ValueError, match="succ_warmup"):
        GlideTrainConfig(succ_warmup=2.0)


# ------------------------------------------------------------------------ packing
def test_packing_dedups_states_and_sums_shared_stretches_exactly() -> None:
    rng = np.random.default_rng(0)
    demo = np.cumsum(rng.normal(size=(30, 2)), axis=0).astype(np.float32)
    trajs = [demo]
    for _ in range(20):  # replays: demo prefix + a random detour + demo suffix, as the wrapper makes them
        x, y = sorted(rng.choice(30, 2, replace=False))
        trajs.append(np.concatenate([demo[: x + 1], rng.normal(size=(2, 2)).astype(np.float32), demo[y:]]))
    labels = rng.random(len(trajs)) < 0.5
    packed = pack_trajectories(trajs, labels)
    assert len(packed.states) < sum(len(t) for t in trajs)
    assert len(packed.run_traj) < sum(len(t) - 1 for t in trajs)  # runs compress shared stretches
    values = torch.randn(len(packed.states), dtype=torch.float64)
    f = values[packed.pair_a] * 2 + values[packed.pair_b]  # any function of (s_t, s_{t+1})
    cum = torch.nn.functional.pad(torch.cumsum(f, 0), (1, 0))
    per = torch.zeros(len(trajs), dtype=torch.float64).index_add_(
        0, packed.run_traj, cum[packed.run_end] - cum[packed.run_start]
    )
    lookup = {tuple(s): v for s, v in zip(packed.states.numpy().tolist(), values.numpy(), strict=True)}
    for i, tr in enumerate(trajs):
        vals = np.array([lookup[tuple(s)] for s in tr.tolist()])
        np.testing.assert_allclose(per[i].item(), np.sum(vals[:-1] * 2 + vals[1:]), rtol=1e-9, atol=1e-9)
    np.testing.assert_array_equal(packed.states[packed.init].numpy(), np.stack([t[0] for t in trajs]))
    np.testing.assert_array_equal(packed.states[packed.final].numpy(), np.stack([t[-1] for t in trajs]))


def test_packing_keeps_every_stride_th_state_and_the_last() -> None:
    tr = np.arange(20, dtype=np.float32).reshape(10, 2)
    packed = pack_trajectories([tr], [True], stride=4)
    np.testing.assert_array_equal(np.sort(packed.states[:, 0].numpy()), [0, 8, 16, 18])
    with pytest.raises(ValueError, match="one label per trajectory"):
        pack_trajectories([tr], [True, False])
    with pytest.raises(ValueError, match="stride"):
        pack_trajectories([tr], [True], stride=0)


# ------------------------------------------------------------------------- losses
def test_losses_match_the_thesis_equations_on_hard_labels() -> None:
    # four trajectories of states 0..; a state's mode is given by its value's integer part
    trajs = [
        np.array([[0.1, 0], [1.1, 0], [2.1, 0]]),  # success: a b c (feasible)
        np.array([[0.2, 0], [2.2, 0], [2.3, 0]]),  # failure: a -> c (one skip, f = -1)
        np.array([[0.3, 0], [1.3, 0], [2.4, 0]]),  # failure without an infeasible move: unexplained (0)
        np.array([[0.4, 0], [2.5, 0], [0.5, 0], [2.6, 0]]),  # failure with two skips: sum -2, clipped to -1
    ]
    labels = [True, False, False, False]
    packed = pack_trajectories(trajs, labels)
    modes = np.floor(packed.states[:, 0].numpy()).astype(int)
    out = glide_losses(_one_hot_logits(modes, 3), packed, torch.tensor(F3, dtype=torch.float32), GlideLossWeights())
    assert out["succ"].item() == pytest.approx(0.0, abs=1e-6)
    assert out["fail"].item() == pytest.approx((-1 + 0 - 1) / 3, abs=1e-6)
    assert out["init"].item() == pytest.approx(0.0, abs=1e-6)
    assert out["final"].item() == pytest.approx(0.0, abs=1e-6)
    assert out["total"].item() == pytest.approx(-2 / 3, abs=1e-5)
    # a success that skips is penalised by its mean infeasibility: one skip of two moves -> 1/2
    packed2 = pack_trajectories([trajs[1]], [True])
    modes2 = np.floor(packed2.states[:, 0].numpy()).astype(int)
    out2 = glide_losses(_one_hot_logits(modes2, 3), packed2, torch.tensor(F3, dtype=torch.float32), GlideLossWeights())
    assert out2["succ"].item() == pytest.approx(0.5, abs=1e-6)


def test_unfinished_failures_are_explained_by_their_last_state() -> None:
    trajs = [
        np.array([[0.1, 0], [1.1, 0], [2.1, 0]]),  # success: a b c
        np.array([[0.2, 0], [1.2, 0]]),  # failure cut short in b: every move feasible
        np.array([[0.3, 0], [2.3, 0]]),  # failure a -> c (a skip), ends in c
    ]
    packed = pack_trajectories(trajs, [True, False, False])
    logits = _one_hot_logits(np.floor(packed.states[:, 0].numpy()).astype(int), 3)
    feas = torch.tensor(F3, dtype=torch.float32)
    thesis = glide_losses(logits, packed, feas, GlideLossWeights())
    assert thesis["fail"].item() == pytest.approx(-0.5, abs=1e-6)  # the short failure is unexplained
    assert thesis["final"].item() == pytest.approx(50 / 3, rel=1e-3)  # ... and its last state is not in c
    arm = glide_losses(logits, packed, feas, GlideLossWeights(unfinished_fails=1.0))
    assert arm["fail"].item() == pytest.approx(-1.0, abs=1e-6)
    assert arm["final"].item() == pytest.approx(0.0, abs=1e-6)  # L_final holds the success only
    half = glide_losses(logits, packed, feas, GlideLossWeights(unfinished_fails=0.5))
    assert half["fail"].item() == pytest.approx(-0.75, abs=1e-6)
    with pytest.raises(ValueError, match="unfinished_fails"):
        GlideLossWeights(unfinished_fails=2.0)


def test_dyn_inputs_predict_the_object_from_the_robot_motion() -> None:
    """Columns (robot x, object - robot r): free (mode 0) r moves against x, carried (mode 1) r stays."""
    x = np.array([0.0, 0.1, 0.3, 0.6, 1.0])
    traj = np.stack([x, np.maximum(0.6 - x, 0.0)], axis=1)
    packed = pack_trajectories([traj], [True])
    logits = _one_hot_logits((packed.states[:, 0] >= 0.6).long().numpy(), 2)
    psi = ForwardModel(1, 2, input_dim=1)
    with torch.no_grad():  # mode 0: dr = -dx; mode 1: dr = 0
        psi.w.copy_(torch.tensor([[[-1.0, 0.0]]]))
        psi.b.zero_()
    weights = GlideLossWeights(dyn=1.0)
    kw = {"psi": psi, "dyn_columns": torch.tensor([1]), "dyn_inputs": torch.tensor([0])}
    same_step = glide_losses(logits, packed, torch.zeros(2, 2), weights, dyn_input_lag=0, **kw)["dyn"]
    previous_step = glide_losses(logits, packed, torch.zeros(2, 2), weights, dyn_input_lag=1, **kw)["dyn"]
    assert same_step.item() == pytest.approx(0.0, abs=1e-10)
    assert previous_step.item() > 1e-3  # the robot accelerates: last step's motion mispredicts
    with pytest.raises(ValueError, match="dyn_input_lag=0 needs dyn_inputs"):
        GlideTrainConfig(dyn_input_lag=0)
    with pytest.raises(ValueError, match="dyn_input_lag"):
        GlideTrainConfig(dyn_input_lag=2, dyn_inputs=(0,))
    with pytest.raises(ValueError, match="dyn_inputs"):
        GlideTrainConfig(dyn_inputs=(-1,))
    config = GlideTrainConfig(epochs=1, dyn_columns=(1,), dyn_inputs=(4,), dyn_input_lag=0)
    with pytest.raises(ValueError, match=r"dyn_inputs .* past the 2 state columns"):
        train_mode_classifier([traj], [True], np.zeros((2, 2)), weights=weights, config=config)


def test_switched_off_terms_are_zero_and_dyn_needs_psi() -> None:
    packed = pack_trajectories([np.zeros((3, 2)) + np.arange(3)[:, None]], [True])
    logits = torch.randn(2, len(packed.states), 3)
    out = glide_losses(
        logits, packed, torch.tensor(F3, dtype=torch.float32), GlideLossWeights().without("succ", "fail")
    )
    assert out["succ"].abs().sum() == 0 and out["fail"].abs().sum() == 0
    assert torch.allclose(out["total"], 10 * (out["init"] + out["final"]))
    with pytest.raises(ValueError, match="forward model"):
        glide_losses(logits, packed, torch.tensor(F3, dtype=torch.float32), GlideLossWeights(dyn=1.0))


# ----------------------------------------------------------------------- training
def _toy_band_data(rng: np.random.Generator, n: int) -> tuple[list[np.ndarray], np.ndarray]:
    """Jump trajectories across three vertical bands; success iff no a -> c skip and ends in c."""
    allowed = F3 == 0
    trajs, labels = [], []
    while len(trajs) < n:
        pts = np.concatenate(
            [rng.uniform([-2, -1], [-0.2, 1], (1, 2)), rng.uniform([-2, -1], [3, 1], (2, 2)), [[2.0, 0.0]]]
        )
        modes = _band_modes(pts)
        trajs.append(pts)
        labels.append(bool(np.all(allowed[modes[:-1], modes[1:]])))
    return trajs, np.array(labels)


def test_training_recovers_the_band_modes_from_success_labels_only() -> None:
    rng = np.random.default_rng(0)
    trajs, labels = _toy_band_data(rng, 400)
    assert 0.2 < labels.mean() < 0.8
    config = GlideTrainConfig(epochs=300, n_heads=2, stride=1, succ_warmup=0.5, seed=0)
    result = train_mode_classifier(trajs, labels, F3, weights=GlideLossWeights(fail=10.0), config=config)
    grid = workspace_grid(np.array([-2.0, -1.0]), np.array([3.0, 1.0]), 60)
    overlap = mode_overlap(result.classifier.predict(grid), _band_modes(grid))
    assert overlap > 0.85, overlap  # chance (one label everywhere) is at most 0.4 here
    assert len(result.head_losses) == 2 and result.classifier.head == int(np.argmin(result.head_losses))
    assert result.history["total"][-1] < result.history["total"][0]
    heads = np.array(result.history["heads"])  # every head's full-weight total, every 50 steps and at the end
    assert heads.shape == (len(range(0, 300, 50)) + 1, 2)
    np.testing.assert_allclose(heads[-1], result.head_losses, rtol=1e-4, atol=1e-4)
    # same seed, same classifier
    again = train_mode_classifier(trajs, labels, F3, weights=GlideLossWeights(fail=10.0), config=config)
    np.testing.assert_array_equal(again.classifier.predict(grid), result.classifier.predict(grid))


def test_progress_bar_is_opt_in_and_quiet_in_logs_on_auto(capsys: pytest.CaptureFixture[str]) -> None:
    trajs, labels = _toy_band_data(np.random.default_rng(1), 40)
    for progress, drawn in ((False, False), (None, False), (True, True)):  # stderr is no terminal under pytest
        config = GlideTrainConfig(epochs=2, n_heads=1, stride=1, seed=0, progress=progress)
        train_mode_classifier(trajs, labels, F3, config=config)
        assert ("GLiDE classifier" in capsys.readouterr().err) is drawn, progress
    with pytest.raises(TypeError, match="progress must be True, False or None"):
        GlideTrainConfig(progress="yes")  # type: ignore[arg-type]


def test_pruning_keeps_the_heads_with_the_lowest_training_loss() -> None:
    trajs, labels = _toy_band_data(np.random.default_rng(3), 200)
    config = GlideTrainConfig(epochs=120, n_heads=4, prune_at=0.5, prune_to=2, seed=1)
    result = train_mode_classifier(trajs, labels, F3, weights=GlideLossWeights(fail=10.0), config=config)
    rows = [len(r) for r in result.history["heads"]]  # logged at steps 0, 50, 100 and 119
    assert rows == [4, 4, 2, 2] and result.classifier.n_heads == 2 and len(result.head_losses) == 2
    assert result.classifier.w1.shape[0] == 2 and result.classifier.predict(np.zeros((3, 2))).shape == (3,)
    # the same run without pruning: pruning keeps the two best heads of step 60 (with their Adam
    # moments), so its best head is at least as good as the second best of the unpruned run
    no_pruning = dataclasses.replace(config, prune_to=4)
    full = train_mode_classifier(trajs, labels, F3, weights=GlideLossWeights(fail=10.0), config=no_pruning)
    assert full.classifier.n_heads == 4
    assert min(result.head_losses) <= sorted(full.head_losses)[1] + 1e-3
    with pytest.raises(ValueError, match="prune_to"):
        GlideTrainConfig(prune_to=0)
    with pytest.raises(ValueError, match="prune_at"):
        GlideTrainConfig(prune_at=1.5)


def _decelerating_paths(rng: np.random.Generator, n: int, *, y_spread: float) -> list[np.ndarray]:
    """Underactuated toy: constant velocity for x < 0, decelerating after (51 states each)."""
    paths = []
    for _ in range(n):
        x = np.array([rng.uniform(-3, -2), rng.uniform(-y_spread, y_spread) if y_spread else 0.0])
        v = np.array([0.1, 0.0])
        pts = [x.copy()]
        for _ in range(50):
            if x[0] >= 0:
                v = 0.9 * v
            x = x + v
            pts.append(x.copy())
        paths.append(np.array(pts))
    return paths


def test_dynamics_loss_separates_modes_with_different_dynamics() -> None:
    """Underactuated toy (eq. 4.3): constant velocity for x < 0, decelerating after; no failures at all."""
    trajs = _decelerating_paths(np.random.default_rng(1), 40, y_spread=1.0)
    truth = [(t[:, 0] >= 0).astype(int) for t in trajs]
    f2 = np.zeros((2, 2))
    labels = np.ones(len(trajs), dtype=bool)
    config = GlideTrainConfig(epochs=400, n_heads=1, stride=1, seed=0)
    with_dyn = train_mode_classifier(trajs, labels, f2, weights=GlideLossWeights(dyn=100.0), config=config)
    without = train_mode_classifier(trajs, labels, f2, weights=GlideLossWeights(), config=config)
    assert with_dyn.psi is not None and without.psi is None

    def acc(res: object) -> float:
        return float(
            np.mean(np.concatenate([res.classifier.predict(t) == m for t, m in zip(trajs, truth, strict=True)]))
        )  # type: ignore[attr-defined]

    assert acc(with_dyn) > 0.9
    assert acc(with_dyn) > acc(without) + 0.05  # init/final alone split midway between starts and ends
    assert with_dyn.history["dyn"][-1] < with_dyn.history["dyn"][0]


def test_dyn_columns_restrict_the_dynamics_loss_to_informative_features() -> None:
    """The toy above plus a jittering column on a tiny range: modelled, it swamps L_dyn; left out, it does not."""
    rng = np.random.default_rng(2)
    paths = _decelerating_paths(rng, 30, y_spread=0.0)
    trajs = [np.concatenate([t, 1e-3 * rng.standard_normal((len(t), 1))], axis=1) for t in paths]
    truth = [(t[:, 0] >= 0).astype(int) for t in paths]
    f2, labels = np.zeros((2, 2)), np.ones(len(trajs), dtype=bool)
    weights = GlideLossWeights(dyn=100.0)

    def acc(dyn_columns: tuple[int, ...] | None) -> float:
        config = GlideTrainConfig(epochs=400, n_heads=1, stride=1, seed=0, dyn_columns=dyn_columns)
        clf = train_mode_classifier(trajs, labels, f2, weights=weights, config=config).classifier
        return float(np.mean(np.concatenate([clf.predict(t) == m for t, m in zip(trajs, truth, strict=True)])))

    assert acc((0, 1)) > 0.9
    assert acc((0, 1)) > acc(None) + 0.05
    with pytest.raises(ValueError, match="dyn_columns"):
        GlideTrainConfig(dyn_columns=())
    with pytest.raises(ValueError, match="past the 3 state columns"):
        train_mode_classifier(
            trajs[:2], labels[:2], f2, weights=weights, config=GlideTrainConfig(epochs=1, dyn_columns=(5,))
        )


def test_training_rejects_bad_input() -> None:
    tr = [np.zeros((3, 2))]
    with pytest.raises(ValueError, match="feasibility"):
        train_mode_classifier(tr, [True], np.ones((3, 3)))
    with pytest.raises(ValueError, match="feasibility"):
        train_mode_classifier(tr, [True], np.zeros(3))
    with pytest.raises(ValueError, match="one label"):
        train_mode_classifier(tr, [True, False], F3)
    with pytest.raises(ValueError, match="init_mode"):
        train_mode_classifier(tr, [True], F3, init_mode=5)


# --------------------------------------------------------------------------- files
def test_classifier_round_trips_through_safetensors(tmp_path: object) -> None:
    clf = ModeClassifier(2, 4, n_heads=3, seed=2)
    clf.set_normalization(np.random.default_rng(0).normal(size=(50, 2)) * 3)
    clf.head = 1
    path = clf.save(tmp_path / "clf.safetensors", extra={"overlap": 0.9})  # type: ignore[operator]
    assert [p.name for p in path.parent.iterdir()] == ["clf.safetensors"]
    back = ModeClassifier.load(path)
    x = np.random.default_rng(1).normal(size=(100, 2)) * 5
    np.testing.assert_allclose(back.predict_proba(x), clf.predict_proba(x), rtol=1e-6)
    assert back.head == 1
    with pytest.raises(ValueError, match="safetensors"):
        clf.save(tmp_path / "clf.pt")  # type: ignore[operator]
    with pytest.raises(ValueError, match="states must have shape"):
        clf.predict(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="head"):
        clf.predict_proba(x, head=7)


# ------------------------------------------------------------------------- metrics
def test_overlap_and_iou() -> None:
    truth = np.array([0, 0, 0, 1, 1, 2])
    assert mode_overlap(truth, truth) == 1.0
    assert mode_overlap(np.zeros(6, dtype=int), truth) == 0.5
    np.testing.assert_allclose(mode_iou(np.zeros(6, dtype=int), truth, 3), [0.5, 0.0, 0.0])
    grid = workspace_grid(np.array([-1.0, -1.0]), np.array([1.0, 1.0]), 5)
    assert grid.shape == (25, 2) and grid.min() == -1 and grid.max() == 1
    with pytest.raises(ValueError, match="equal-length"):
        mode_overlap(np.zeros(3), np.zeros(4))
    with pytest.raises(ValueError, match="resolution"):
        workspace_grid(np.zeros(2), np.ones(2), 1)


def test_kmeans_baseline_numbers_clusters_in_temporal_order() -> None:
    rng = np.random.default_rng(0)
    centers = np.array([[5.0, 5.0], [0.0, 0.0], [-5.0, 5.0]])  # visited in this order
    demos = [np.concatenate([c + 0.1 * rng.normal(size=(10, 2)) for c in centers]) for _ in range(3)]
    km = KMeansSegmentation(3, seed=0).fit(demos)
    np.testing.assert_array_equal(km.predict(centers), [0, 1, 2])
    with pytest.raises(RuntimeError, match="before fit"):
        KMeansSegmentation(3).predict(centers)
    with pytest.raises(ValueError, match="num_modes"):
        KMeansSegmentation(1)
