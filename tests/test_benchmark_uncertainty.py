"""The uncertainty benchmark's bound on estimates read off the learned reward alone."""

import numpy as np
from scipy.stats import spearmanr

from benchmarks.uncertainty import binned_error


def test_the_bound_ranks_an_error_that_follows_the_reward_and_names_its_peak_decile() -> None:
    reward = np.random.default_rng(0).normal(size=1000)
    error = np.abs(reward - 1.5)  # largest far below the reward's top: peaks in the lowest decile

    best, peak = binned_error(reward, error)

    assert spearmanr(best, error)[0] > 0.9
    assert peak == 0


def test_the_bound_cannot_rank_an_error_unrelated_to_the_reward() -> None:
    rng = np.random.default_rng(1)
    reward, error = rng.normal(size=20_000), rng.random(20_000)

    best, _ = binned_error(reward, error)

    assert abs(spearmanr(best, error)[0]) < 0.05
