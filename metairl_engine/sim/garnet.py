"""Garnet MDPs (Archibald, McKinnon & Thomas 1995; Bhatnagar et al. 2009): random stochastic MDPs with no
geometry at all, the standard family for methods that should not rely on a grid.

Garnet(n, m, b): ``n`` states, ``m`` actions, and each (state, action) leads to ``b`` distinct next states
drawn uniformly, with probabilities the gaps between b − 1 uniform cut points of [0, 1]. The reward is linear
in random binary features, as IRL papers on Garnets give it (each of F features on a state with probability
0.3, weights N(0, 1), the reward scaled to a largest |r| of 1). What it tests: an MDP with features and no
layout whose transitions are neither local nor deterministic, so nothing about a state's place carries over
to its neighbours.
"""

from __future__ import annotations

import numpy as np

from metairl_engine.mdp import MDP
from metairl_engine.sim.benchmark import RewardWorld

FEATURE_PROBABILITY = 0.3
"""Chance that a binary feature is on at a state."""


def garnet_transitions(
    rng: np.random.Generator, *, n_states: int, n_actions: int, branching: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The sparse transitions (s, a, next, p) of Garnet(n_states, n_actions, branching), one block of
    ``branching`` entries per (s, a) in state-major order."""
    pairs = n_states * n_actions
    nxt = np.stack([rng.choice(n_states, size=branching, replace=False) for _ in range(pairs)])
    cuts = np.sort(rng.random((pairs, branching - 1)), axis=1)
    p = np.diff(np.concatenate([np.zeros((pairs, 1)), cuts, np.ones((pairs, 1))], axis=1), axis=1)
    s = np.repeat(np.arange(n_states), n_actions * branching)
    a = np.tile(np.repeat(np.arange(n_actions), branching), n_states)
    return s, a, nxt.ravel(), p.ravel()


def make_garnet(
    *,
    seed: int,
    n_states: int = 100,
    n_actions: int = 4,
    branching: int = 3,
    n_features: int = 10,
    gamma: float = 0.9,
    with_features: bool = True,
) -> RewardWorld:
    """A seeded Garnet world: its MDP (with the binary features unless ``with_features`` is False) and its
    reward, linear in those features; ``size`` is √n_states, the horizon scale of the other families."""
    rng = np.random.default_rng(seed)
    s, a, nxt, p = garnet_transitions(rng, n_states=n_states, n_actions=n_actions, branching=branching)
    features = (rng.random((n_states, n_features)) < FEATURE_PROBABILITY).astype(np.float32)
    reward = features @ rng.normal(size=n_features)
    reward = reward / max(float(np.abs(reward).max()), 1e-12)
    mdp = MDP.build(
        gamma=gamma,
        n_states=n_states,
        n_actions=n_actions,
        s=s,
        a=a,
        next=nxt,
        p=p,
        features=features if with_features else None,
    )
    return RewardWorld(size=round(np.sqrt(n_states)), reward=reward.astype(np.float32), mdp=mdp)
