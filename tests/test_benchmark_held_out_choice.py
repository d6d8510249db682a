"""The held-out choice probe's temperature: it judges how a policy ranks the held-out actions, not how sure it is."""

import numpy as np
import pytest

from benchmarks.held_out_choice import calibrated_nll, tempered_nll


def test_at_temperature_one_the_nll_is_the_policys_own() -> None:
    log_policy = np.log(np.array([[0.7, 0.2, 0.1], [0.1, 0.1, 0.8]]))
    actions = np.array([1, 2])

    assert tempered_nll(log_policy, actions, 1.0) == pytest.approx(-np.log(0.2) - np.log(0.8))


def test_a_sure_policy_that_ranks_the_actions_right_beats_a_uniform_one_only_once_tempered() -> None:
    actions = np.array([0] * 80 + [1] * 20)  # the held-out demonstrations take action 0 four times in five
    sure, uniform = np.log(np.tile([0.99, 0.01], (100, 1))), np.log(np.full((100, 2), 0.5))

    assert tempered_nll(sure, actions, 1.0) > tempered_nll(
        uniform, actions, 1.0
    )  # charged for its confidence
    tempered, beta = calibrated_nll(sure, actions)
    assert tempered < calibrated_nll(uniform, actions)[0] and beta < 1
    assert tempered == pytest.approx(-100 * (0.8 * np.log(0.8) + 0.2 * np.log(0.2)), rel=1e-4)
