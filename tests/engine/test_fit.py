"""The meta-IRL fit: exact gradients, recovery, sharing, determinism, batching, transitions, callbacks, inputs."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from metairl_engine import MDP, FitConfig, InvalidInput, Trajectory
from metairl_engine.backups import QRows, successors
from metairl_engine.errors import Cancelled, Diverged
from metairl_engine.evidence import NEXT_TO_VISITED, VISITED, evidence
from metairl_engine.fit import CONVERGED_STEPS, HeldOutStopper, _Problem, fit, gradient_step, objective
from metairl_engine.grids import grid_mdp
from metairl_engine.metrics import pearson
from metairl_engine.networks import StackedMLP
from metairl_engine.planning import transition_matrix
from metairl_engine.results import Progress
from metairl_engine.sim.terrain import make_tasks, make_world
from tests.engine.helpers import as_sparse, goal_tasks_with_features, small_grid, soft_demos, task


def bump_reward(size: int) -> np.ndarray:
    """A smooth reward on a size×size grid: a bump near one corner, a dip near the other."""
    ys, xs = np.divmod(np.arange(size * size), size)
    return np.exp(-((xs - 1) ** 2 + (ys - 3) ** 2) / 3.0) - 0.8 * np.exp(
        -((xs - 3) ** 2 + (ys - 1) ** 2) / 2.0
    )


def terrain_tasks(*, seed: int, n_tasks: int, n_demos: int) -> tuple[list, list]:
    """Small terrain world's tasks as (TaskData list, SimTask list)."""
    world = make_world(size=8, n_hills=3, seed=seed)
    sims = make_tasks(world, n_tasks=n_tasks, n_demos=n_demos, seed=seed + 100)
    return [task(world.mdp, s.trajectories) for s in sims], sims


class LossModule(torch.nn.Module):
    """The fit's training loss as a module of both networks' parameters (for functional_call)."""

    def __init__(self, problem: _Problem, vr: StackedMLP, base: StackedMLP, config: FitConfig):
        super().__init__()
        self.problem, self.vr, self.base, self.config = problem, vr, base, config

    def forward(self) -> torch.Tensor:
        block = self.problem.blocks[0]
        f, r_b = self.vr(block.inputs_u), self.base(block.inputs_base)
        return objective(self.problem, block, f, r_b, self.config)[0]


@pytest.mark.parametrize("sharing", ["l2", "huber", "std", "entropy"])
def test_loss_gradient_matches_finite_differences_in_float64(sharing: str) -> None:
    mdp = small_grid(size=3)
    reward = bump_reward(3)
    tasks = [task(mdp, soft_demos(mdp, reward, starts=np.array([0, 4]), length=3, seed=s)) for s in (0, 1)]
    # ω = 1: the loss's own gradient (the baseline's row weights scale its gradient on purpose; tested apart)
    config = FitConfig(
        sharing=sharing,  # type: ignore[arg-type]
        backup="logsumexp",
        hidden=(4,),
        holdout_fraction=0.0,
        ensemble=1,
        baseline_elsewhere_weight=1.0,
    )
    problem = _Problem(tasks, config)
    block = problem.blocks[0]
    block.inputs_u, block.inputs_base = block.inputs_u.double(), block.inputs_base.double()
    problem.gamma = problem.gamma.double()
    gen = torch.Generator().manual_seed(0)
    vr = StackedMLP(n_members=2, n_inputs=2, hidden=(4,), tabular=False, generator=gen).double()
    base = StackedMLP(n_members=1, n_inputs=2, hidden=(4,), tabular=False, generator=gen).double()
    module = LossModule(problem, vr, base, config)
    names = [n for n, _ in module.named_parameters()]
    params = tuple(p.detach().clone().requires_grad_() for p in module.parameters())

    def loss_of(*flat: torch.Tensor) -> torch.Tensor:
        return torch.func.functional_call(module, dict(zip(names, flat, strict=True)), ())

    assert torch.autograd.gradcheck(loss_of, params, eps=1e-6, atol=1e-5)


def test_recovers_a_known_reward_from_demonstrations_starting_everywhere() -> None:
    mdp = small_grid(size=5)
    reward = bump_reward(5)
    starts = np.repeat(np.arange(mdp.n_states), 20)
    demos = soft_demos(mdp, reward, starts=starts, length=5, seed=0, confidence=3.0)
    config = FitConfig(
        sharing="none", backup="logsumexp", confidence=3.0, max_steps=400, holdout_fraction=0.0
    )
    result = fit([task(mdp, demos)], config)
    assert pearson(result.rewards[0], reward) >= 0.9


def test_sharing_beats_no_sharing_with_few_demonstrations() -> None:
    gains = []
    for seed in range(3):
        tasks, sims = terrain_tasks(seed=seed, n_tasks=4, n_demos=2)
        scores = {}
        for sharing in ("none", "huber"):
            r = fit(tasks, FitConfig(sharing=sharing, max_steps=300))
            scores[sharing] = np.mean(
                [
                    pearson(r.rewards[i], s.true_reward, mask=np.arange(len(s.true_reward)) != s.goal)
                    for i, s in enumerate(sims)
                ]
            )
        gains.append(scores["huber"] - scores["none"])
    assert np.mean(gains) > 0.05


def test_same_seed_gives_bit_identical_results_and_another_seed_does_not() -> None:
    tasks, _ = terrain_tasks(seed=0, n_tasks=2, n_demos=2)
    config = FitConfig(max_steps=30)
    a, b = fit(tasks, config), fit(tasks, config)
    c = fit(tasks, FitConfig(max_steps=30, seed=1))
    assert np.array_equal(a.rewards, b.rewards) and np.array_equal(a.baseline, b.baseline)
    assert [h.loss for h in a.history] == [h.loss for h in b.history]
    assert not np.array_equal(a.rewards, c.rewards)


def test_batched_networks_equal_each_network_alone() -> None:
    features = torch.rand(7, 3, generator=torch.Generator().manual_seed(0))
    batched = StackedMLP(n_members=3, n_inputs=3, hidden=(5, 4), tabular=False, generator=torch.Generator())
    out = batched(features)
    for t in range(3):
        alone = StackedMLP(n_members=1, n_inputs=3, hidden=(5, 4), tabular=False, generator=torch.Generator())
        with torch.no_grad():
            for mine, theirs in zip(alone.parameters(), batched.parameters(), strict=True):
                mine.copy_(theirs[t : t + 1])
        assert torch.allclose(alone(features)[0], out[t], atol=1e-6)


def test_every_input_form_gives_the_same_outputs_and_gradients() -> None:
    """Tabular indices and one-hot features (an embedding row is a linear layer on a one-hot input), shared
    by the networks or each network's own: one function, whichever gather or fused product computes it."""
    states = torch.tensor([[0, 3, 3, 5], [5, 1, 0, 2]])  # each network's own states, one repeated
    tabular = StackedMLP(n_members=2, n_inputs=6, hidden=(5, 4), tabular=True, generator=torch.Generator())
    on_features = StackedMLP(
        n_members=2, n_inputs=6, hidden=(5, 4), tabular=False, generator=torch.Generator()
    )
    on_features.load_state_dict(tabular.state_dict())

    def outputs_and_gradients(net: StackedMLP, inputs: torch.Tensor) -> list[torch.Tensor]:
        net.zero_grad()
        out = net(inputs)
        (out * torch.arange(1.0, 1.0 + out.numel()).reshape(out.shape)).sum().backward()
        return [out.detach(), *(p.grad.clone() for p in net.parameters() if p.grad is not None)]

    one_hot = torch.eye(6)
    for indices in (states, states[0]):  # (T, N) per network, (N,) shared
        got = outputs_and_gradients(tabular, indices)
        expected = outputs_and_gradients(on_features, one_hot[indices])
        assert len(got) == len(expected) == 7  # outputs, then 3 weights and 3 biases
        assert all(torch.allclose(g, e, atol=1e-6) for g, e in zip(got, expected, strict=True))


@pytest.mark.parametrize("hidden", [(), (5,), (5, 4)])
def test_stacked_networks_compute_each_member_s_plain_mlp(hidden: tuple[int, ...]) -> None:
    """The bias as a column of ones and the width-1 last layer as a product and a sum compute, per member,
    relu(x·W + b) layer by layer, on shared (N, F) and per-network (T, N, F) inputs."""
    net = StackedMLP(
        n_members=3, n_inputs=2, hidden=hidden, tabular=False, generator=torch.Generator().manual_seed(1)
    )
    x = torch.rand(3, 7, 2, generator=torch.Generator().manual_seed(2))

    def plain(member: int, inputs: torch.Tensor) -> torch.Tensor:
        h = inputs
        for layer, (w, b) in enumerate(zip(net.weights, net.biases, strict=True)):
            h = h @ w[member] + b[member, 0]
            if layer < len(hidden):
                h = torch.relu(h)
        return h.squeeze(-1)

    expected = torch.stack([plain(t, x[t]) for t in range(3)])
    assert torch.allclose(net(x), expected, atol=1e-6)
    assert torch.allclose(net(x[0]), torch.stack([plain(t, x[0]) for t in range(3)]), atol=1e-6)


def test_deterministic_and_sparse_transitions_give_the_same_q() -> None:
    det, other = small_grid(size=4), small_grid(size=4, gamma=0.5)
    sparse = as_sparse(other)
    states = np.array([0, 5, 15, 3, 3])
    tasks = np.array([0, 0, 1, 1, 0])
    identity = np.arange(det.n_states)
    f = torch.randn(2, det.n_states, generator=torch.Generator().manual_seed(0))
    gathered = QRows([det, other], tasks, states, columns=identity, n_columns=det.n_states)(f)
    multiplied = QRows([det, sparse], tasks, states, columns=identity, n_columns=det.n_states)(f)
    assert multiplied.shape == (5, det.n_actions)
    assert torch.allclose(gathered, multiplied)
    assert det.next_state is not None
    assert torch.equal(gathered[0], f[0, torch.from_numpy(det.next_state[0]).long()])


def test_stochastic_q_and_its_gradient_equal_the_dense_transition_product() -> None:
    mdp = grid_mdp(width=3, height=3, moves=4, stay=True, slip=0.3, gamma=0.9)
    states, tasks = np.array([0, 4, 8, 4, 2]), np.array([0, 1, 1, 0, 1])
    f = torch.randn(2, 9, generator=torch.Generator().manual_seed(0), requires_grad=True)
    weights = torch.randn(5, mdp.n_actions, generator=torch.Generator().manual_seed(1))
    q = QRows([mdp, mdp], tasks, states, columns=np.arange(9), n_columns=9)(f)
    p = torch.from_numpy(transition_matrix(mdp).toarray()).float().reshape(9, mdp.n_actions, 9)
    expected = torch.einsum("nas,ns->na", p[states], f[tasks])  # Q(s, a) = Σ_s' P(s'|s, a) f(s')
    assert torch.allclose(q, expected, atol=1e-6)
    (grad,) = torch.autograd.grad((weights * q).sum(), f)
    (expected_grad,) = torch.autograd.grad((weights * expected).sum(), f)
    assert torch.allclose(grad, expected_grad, atol=1e-6) and grad.abs().sum() > 0


def test_fit_runs_on_sparse_and_tabular_mdps() -> None:
    mdp = small_grid(size=3)
    demos = soft_demos(mdp, bump_reward(3), starts=np.array([0, 8]), length=4, seed=0)
    tabular = type(mdp)(n_states=9, n_actions=mdp.n_actions, gamma=0.9, next_state=mdp.next_state)
    result = fit([task(as_sparse(mdp), demos), task(as_sparse(mdp), demos)], FitConfig(max_steps=5))
    assert result.rewards.shape == (2, 9) and result.policies.shape == (2, 9, mdp.n_actions)
    assert np.allclose(result.policies.sum(axis=-1), 1.0, atol=1e-5)
    assert fit([task(tabular, demos)], FitConfig(max_steps=5, sharing_states="visited")).rewards.shape == (
        1,
        9,
    )


def test_progress_is_reported_every_step_and_best_step_is_kept() -> None:
    tasks, _ = terrain_tasks(seed=0, n_tasks=2, n_demos=2)
    seen: list[Progress] = []
    result = fit(tasks, FitConfig(max_steps=40, patience=0), progress=seen.append)
    assert [p.step for p in seen] == list(range(1, 41))
    assert result.history == seen
    assert all(p.heldout_nll is not None and p.elapsed_s >= 0 for p in seen)
    assert result.best_step >= 1 + int(np.argmin(np.array([p.heldout_nll for p in seen], dtype=float)))


def test_stopper_keeps_steps_within_one_se_and_stops_after_patience_steps_without_meaningful_progress() -> (
    None
):
    stopper = HeldOutStopper(patience=3)
    assert stopper.update(1, torch.tensor([1.0, 3.0]))  # best 2.0, standard error 1.414 / √2 = 1.0: progress
    assert stopper.update(2, torch.tensor([2.4, 3.4]))  # 2.9 ≤ 2.0 + 1.0: kept, not a new best
    assert stopper.update(3, torch.tensor([1.5, 2.1]))  # new best 1.8, but not below 2.0 − 1.0: no progress
    assert stopper.update(4, torch.tensor([0.8, 1.0]))  # 0.9 < 1.0: progress, standard error 0.1
    assert stopper.update(5, torch.tensor([0.85, 0.87]))  # a new best within 0.1 of 0.9: kept, no progress
    assert not stopper.update(6, torch.tensor([3.0, 3.2]))  # 3.1 > 0.86 + 0.01
    assert not stopper.should_stop(6)
    assert stopper.should_stop(7) and stopper.kept_step == 5  # three steps since the progress at step 4


def test_loss_tolerance_stops_only_after_several_flat_steps_in_a_row() -> None:
    tasks, _ = terrain_tasks(seed=0, n_tasks=1, n_demos=1)
    always_flat = fit(tasks, FitConfig(max_steps=100, patience=0, tolerance=1.0))
    assert len(always_flat.history) == 1 + CONVERGED_STEPS  # step 1 has no previous loss to compare with
    assert len(fit(tasks, FitConfig(max_steps=30, patience=0, tolerance=0.0)).history) == 30


def test_should_stop_cancels_the_fit() -> None:
    tasks, _ = terrain_tasks(seed=0, n_tasks=1, n_demos=1)
    calls = []

    def stop() -> bool:
        calls.append(1)
        return len(calls) > 3

    with pytest.raises(Cancelled):
        fit(tasks, FitConfig(max_steps=100), should_stop=stop)
    assert len(calls) == 4


def test_tasks_with_other_states_or_features_are_rejected_with_pointers() -> None:
    a, b = small_grid(size=3), small_grid(size=4)
    demo = [Trajectory.of([0, 1], [0])]
    with pytest.raises(InvalidInput) as exc:
        fit([task(a, demo), task(a, demo), task(b, demo)])
    assert [i.pointer for i in exc.value.issues] == ["/tasks/2/mdp"]
    assert "has 16 states but task 0 has 9" in str(exc.value)
    shifted = MDP.build(gamma=0.9, next_state=a.next_state, features=np.asarray(a.features) + 1)
    with pytest.raises(InvalidInput, match="different state features"):
        fit([task(a, demo), task(shifted, demo)])


def test_bad_trajectories_are_rejected_with_task_and_step() -> None:
    a = small_grid(size=3)
    with pytest.raises(InvalidInput) as exc:
        fit([task(a, [Trajectory.of([0, 1], [0])]), task(a, [Trajectory.of([0, 99], [0])])])
    assert [i.pointer for i in exc.value.issues] == ["/tasks/1/trajectories/0/states/1"]


def test_the_baseline_learns_by_the_evidence_at_each_state_and_the_task_is_pulled_alike() -> None:
    mdp = small_grid(size=5)
    demos = soft_demos(mdp, bump_reward(5), starts=np.array([0, 24]), length=2, seed=0)
    acted = [Trajectory(t.states[: len(t.actions)], t.actions) for t in demos]  # the steps the fit trains on
    level = torch.from_numpy(evidence(mdp, acted))  # 1 visited, ½ one move from a visit, 0 elsewhere
    assert {float(v) for v in level.unique()} == {VISITED, NEXT_TO_VISITED, 0.0}
    runs = []
    for weight in (1.0, 0.25):
        config = FitConfig(baseline_elsewhere_weight=weight, sharing="l2", holdout_fraction=0.0, ensemble=1)
        problem = _Problem([task(mdp, demos)], config)
        block = problem.blocks[0]
        gen = torch.Generator().manual_seed(0)
        f = StackedMLP(n_members=1, n_inputs=2, hidden=(8,), tabular=False, generator=gen)(block.inputs_u)
        r_b = StackedMLP(n_members=1, n_inputs=2, hidden=(8,), tabular=False, generator=gen)(
            block.inputs_base
        )
        f, r_b = f.detach().requires_grad_(), r_b.detach().requires_grad_()
        loss = objective(problem, block, f, r_b, config)[0]
        loss.backward()
        assert f.grad is not None and r_b.grad is not None
        runs.append((loss.detach(), f.grad, r_b.grad[0, np.argsort(block.base_states)]))  # by state
    (loss_1, task_grad_1, base_grad_1), (loss_w, task_grad_w, base_grad_w) = runs
    assert torch.equal(loss_1, loss_w) and torch.allclose(task_grad_1, task_grad_w)
    # a visit counts 1, a neighbour of one ½, elsewhere ω = 0.25 (one task: every visit has one witness)
    expected = torch.where(level > 0, level, 0.25).to(base_grad_1.dtype)
    assert torch.allclose(base_grad_w, expected * base_grad_1)
    assert base_grad_1[level == 0].abs().sum() > 0 and base_grad_1[level == NEXT_TO_VISITED].abs().sum() > 0


def test_a_state_one_task_alone_visited_teaches_the_baseline_from_every_task() -> None:
    mdp = small_grid(size=5)
    starts = {"a": [0], "b": [0], "c": [24]}  # a and b visit the corner at 0, c alone the one at 24
    demos = {
        name: soft_demos(mdp, bump_reward(5), starts=np.array(s), length=2, seed=0)
        for name, s in starts.items()
    }
    level = {
        name: evidence(mdp, [Trajectory(t.states[: len(t.actions)], t.actions) for t in d])
        for name, d in demos.items()
    }
    config = FitConfig(baseline_elsewhere_weight=0.1, sharing="l2", holdout_fraction=0.0, ensemble=1)
    problem = _Problem([task(mdp, d) for d in demos.values()], config)
    block = problem.blocks[0]
    assert block.share_weight is not None
    weight = np.zeros((3, mdp.n_states), dtype=np.float32)
    weight[block.share_tasks.numpy(), block.base_states[block.share_base.numpy()]] = (
        block.share_weight.numpy()
    )
    witnesses = np.sum([(v == VISITED).astype(int) for v in level.values()], axis=0)
    assert set(witnesses) >= {0, 1, 2}
    for row, name in zip(weight, starts, strict=True):
        # one witness: every task counts 1; otherwise the task's own evidence: 1 visited, ½ next to a visit, else ω
        expected = np.where(witnesses == 1, 1.0, np.where(level[name] > 0, level[name], 0.1))
        assert np.allclose(row, expected), name
    assert np.allclose(weight[2][witnesses == 2], 0.1) and np.allclose(weight[0][witnesses == 2], 1.0)


@pytest.mark.parametrize("sharing", ["none", "huber"])
def test_chunked_gradient_step_equals_the_direct_one(sharing: str) -> None:
    tasks, _ = terrain_tasks(seed=0, n_tasks=3, n_demos=2)
    config = FitConfig(sharing=sharing, ensemble=1)  # type: ignore[arg-type]
    problem = _Problem(tasks, config)
    grads = []
    for chunk in (10_000, 7):
        gen = torch.Generator().manual_seed(0)
        vr = StackedMLP(n_members=3, n_inputs=2, hidden=(8, 4), tabular=False, generator=gen)
        base = StackedMLP(n_members=1, n_inputs=2, hidden=(8, 4), tabular=False, generator=gen)
        loss = gradient_step(problem, vr, base, config, chunk=chunk)[0]
        grads.append((loss, [p.grad for p in [*vr.parameters(), *base.parameters()]]))
    assert torch.allclose(grads[0][0], grads[1][0])
    for direct, chunked in zip(grads[0][1], grads[1][1], strict=True):
        assert (direct is None) == (chunked is None) == (sharing == "none" and direct is None)
        if direct is not None:
            assert chunked is not None and torch.allclose(direct, chunked, atol=1e-6)


def test_fit_on_the_cpu_device_gives_bit_identical_results_to_the_default() -> None:
    tasks, _ = terrain_tasks(seed=0, n_tasks=2, n_demos=2)
    config = FitConfig(max_steps=30)
    default, on_cpu = fit(tasks, config), fit(tasks, config, device="cpu")
    for name in ("baseline", "rewards", "values", "policies"):
        assert isinstance(getattr(on_cpu, name), np.ndarray)
        assert np.array_equal(getattr(default, name), getattr(on_cpu, name)), name
    assert [h.loss for h in default.history] == [h.loss for h in on_cpu.history]
    assert default.best_step == on_cpu.best_step


def tensors_in(value: object) -> list[torch.Tensor]:
    """Every tensor reachable from ``value`` through lists, tuples and the attributes of engine objects."""
    if isinstance(value, torch.Tensor):
        return [value]
    if isinstance(value, list | tuple):
        return [t for item in value for t in tensors_in(item)]
    if type(value).__module__.startswith("metairl_engine") and hasattr(value, "__dict__"):
        return [t for item in vars(value).values() for t in tensors_in(item)]
    return []


@pytest.mark.parametrize("sparse", [False, True])
def test_moving_a_problem_moves_every_tensor_it_holds_and_the_inputs_it_builds(sparse: bool) -> None:
    mdp = small_grid(size=3)
    demos = soft_demos(mdp, bump_reward(3), starts=np.arange(9), length=4, seed=0)
    if sparse:
        mdp = as_sparse(mdp)
    problem = _Problem([task(mdp, demos), task(mdp, demos)], FitConfig(ensemble=2))
    before = tensors_in(problem)
    assert len(before) > 10 and all(t.device.type == "cpu" for t in before)
    moved = problem.to(torch.device("meta"))  # a device every torch build has, standing in for a GPU
    assert moved is problem
    after = tensors_in(problem)
    assert len(after) == len(before) and all(t.device.type == "meta" for t in after)
    assert problem.inputs(np.arange(4)).device.type == "meta"


def test_each_network_is_evaluated_only_on_the_states_its_own_rows_need() -> None:
    mdp = small_grid(size=5)
    reward = bump_reward(5)
    corners = [np.array([0, 1, 5]), np.array([24, 23, 19])]
    tasks = [task(mdp, soft_demos(mdp, reward, starts=s, length=2, seed=0)) for s in corners]
    problem = _Problem(tasks, FitConfig(sharing="none", ensemble=1, holdout_fraction=0.0))
    (block,) = problem.blocks
    needed = [
        set(successors([mdp], np.zeros(len(s), dtype=np.int64), s).tolist())
        for s in (np.concatenate([tr.states[:-1] for tr in t.trajectories]) for t in tasks)
    ]
    assert [set(block.states_u[j].tolist()) for j in range(2)] == needed  # padding repeats an own state
    assert block.states_u.shape[1] == max(len(n) for n in needed) < len(needed[0] | needed[1])


def test_no_hidden_layer_gives_a_baseline_affine_in_the_features() -> None:
    features = np.random.default_rng(0).normal(size=(25, 3)).astype(np.float32)
    result = fit(goal_tasks_with_features(features), FitConfig(hidden=(), max_steps=50, seed=0))
    design = np.c_[features, np.ones(25)]
    coef = np.linalg.lstsq(design, result.baseline, rcond=None)[0]
    assert result.baseline.std() > 0.01
    assert np.abs(design @ coef - result.baseline).max() < 1e-5


def test_a_fit_whose_loss_stops_being_finite_stops_saying_which_settings_to_lower() -> None:
    features = np.random.default_rng(0).normal(size=(25, 3)).astype(np.float32)
    with pytest.raises(Diverged, match=r"diverged at step 1: its loss became nan\. Lower config\.confidence"):
        fit(goal_tasks_with_features(features), FitConfig(confidence=1e300, hidden=(8,), max_steps=20))
