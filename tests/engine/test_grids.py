"""Grid MDPs: numbering, walls, move sets, slip and the paper's velocity grid."""

import numpy as np
import pytest

from metairl_engine import InvalidInput, Trajectory, validate_trajectories
from metairl_engine.grids import (
    DIRECTION_NAMES,
    DIRECTIONS,
    direction_index,
    grid_mdp,
    grid_moves,
    velocity_coords,
    velocity_state,
)


def pointers(exc: pytest.ExceptionInfo[InvalidInput]) -> list[str]:
    return [i.pointer for i in exc.value.issues]


def test_direction_table_is_counter_clockwise_from_right_with_forward_as_plus_y() -> None:
    assert DIRECTIONS.tolist() == [[1, 0], [1, 1], [0, 1], [-1, 1], [-1, 0], [-1, -1], [0, -1], [1, -1]]
    assert DIRECTION_NAMES[0] == "right" and DIRECTION_NAMES[2] == "forward"
    assert DIRECTION_NAMES[5] == "backward left"
    assert direction_index(DIRECTIONS[:, 0], DIRECTIONS[:, 1]).tolist() == list(range(8))
    assert int(direction_index(np.array(0), np.array(0))) == -1


def test_plain_grid_sizes_layout_and_features() -> None:
    m = grid_mdp(width=5, height=3, gamma=0.9)
    assert (m.n_states, m.n_actions, m.is_deterministic) == (15, 4, True)
    assert m.layout is not None and (m.layout.width, m.layout.height, m.layout.channels) == (5, 3, 1)
    assert m.features is not None and m.features.dtype == np.float32 and m.features.shape == (15, 2)
    # state = y * width + x; features are (x / (W-1), y / (H-1)).
    assert m.features[2 * 5 + 4].tolist() == [1.0, 1.0]
    assert m.features[1 * 5 + 2].tolist() == [0.5, 0.5]


def test_plain_grid_moves_east_north_west_south_and_walls_keep_the_agent() -> None:
    m = grid_mdp(width=4, height=3, gamma=0.9)
    assert m.next_state is not None
    centre = 1 * 4 + 1
    assert m.next_state[centre].tolist() == [centre + 1, centre + 4, centre - 1, centre - 4]
    corner = 0  # (0, 0): west and south are walls
    assert m.next_state[corner].tolist() == [1, 4, 0, 0]
    top_right = 2 * 4 + 3
    assert m.next_state[top_right].tolist() == [top_right, top_right, top_right - 1, top_right - 4]


def test_eight_moves_and_stay() -> None:
    m = grid_mdp(width=3, height=3, moves=8, stay=True, gamma=0.5)
    assert m.n_actions == 9 and m.next_state is not None
    assert grid_moves(moves=8, stay=True)[-1].tolist() == [0, 0]
    assert m.next_state[4].tolist() == [5, 8, 7, 6, 3, 0, 1, 2, 4]
    assert m.next_state[0].tolist() == [1, 4, 3, 0, 0, 0, 0, 0, 0]


def test_slip_is_sparse_sums_to_one_and_merges_duplicate_targets() -> None:
    m = grid_mdp(width=4, height=4, slip=0.3, gamma=0.9)
    assert m.sparse is not None and not m.is_deterministic
    t = m.sparse
    sums = np.bincount(t.s * m.n_actions + t.a, weights=t.p)
    np.testing.assert_allclose(sums, 1.0, atol=1e-6)
    keys = (t.s.astype(np.int64) * m.n_actions + t.a) * m.n_states + t.next
    assert len(np.unique(keys)) == len(keys)  # no duplicate (s, a, next)
    # Corner 0, action east: stays (west, south walls: 2 × 0.1) or north (0.1) or east (0.7).
    row = (t.s == 0) & (t.a == 0)
    assert dict(zip(t.next[row].tolist(), t.p[row].tolist(), strict=True)) == pytest.approx(
        {0: 0.2, 1: 0.7, 4: 0.1}
    )
    # An interior state has at most 4 targets per action: sparse, not dense.
    assert len(t.p) < m.n_states * m.n_actions * m.n_actions


def test_velocity_grid_numbering_features_and_layout() -> None:
    w, h = 6, 4
    m = grid_mdp(width=w, height=h, velocity=True, gamma=0.9)
    assert (m.n_states, m.n_actions) == (8 * w * h, 8)
    assert m.layout is not None and m.layout.channels == 8
    s = velocity_state(2, 3, 5, width=w, height=h)
    assert int(s) == (5 * h + 3) * w + 2
    assert [int(v) for v in velocity_coords(s, width=w, height=h)] == [2, 3, 5]
    assert m.features is not None and m.features.shape == (8 * w * h, 10)
    np.testing.assert_allclose(m.features[s], [2 / 5, 3 / 3, 0, 0, 0, 0, 0, 1, 0, 0])


def test_velocity_action_moves_one_cell_and_sets_the_velocity_from_every_state() -> None:
    w, h = 5, 4
    m = grid_mdp(width=w, height=h, velocity=True, gamma=0.9)
    assert m.next_state is not None
    x, y, _ = velocity_coords(np.arange(m.n_states), width=w, height=h)
    for d in range(8):
        nx, ny, nd = velocity_coords(m.next_state[:, d], width=w, height=h)
        tx, ty = x + DIRECTIONS[d, 0], y + DIRECTIONS[d, 1]
        inside = (tx >= 0) & (tx < w) & (ty >= 0) & (ty < h)
        assert (nd == d).all()
        assert (nx == np.where(inside, tx, x)).all() and (ny == np.where(inside, ty, y)).all()


def test_velocity_grid_with_slip_keeps_the_chosen_direction_most_likely() -> None:
    m = grid_mdp(width=3, height=3, velocity=True, slip=0.2, gamma=0.9)
    assert m.sparse is not None
    t = m.sparse
    np.testing.assert_allclose(np.bincount(t.s * 8 + t.a, weights=t.p), 1.0, atol=1e-6)
    centre = int(velocity_state(1, 1, 0, width=3, height=3))
    row = (t.s == centre) & (t.a == 2)
    best = t.next[row][np.argmax(t.p[row])]
    assert int(best) == int(velocity_state(1, 2, 2, width=3, height=3))
    np.testing.assert_allclose(t.p[row].max(), 0.8, atol=1e-6)


def test_full_size_velocity_grid_builds_80000_states() -> None:
    m = grid_mdp(width=100, height=100, velocity=True, gamma=0.95)
    assert (m.n_states, m.n_actions, m.n_features) == (80_000, 8, 10)
    traj = Trajectory.of(
        velocity_state(
            np.array([50, 51, 51]), np.array([50, 50, 51]), np.array([0, 0, 2]), width=100, height=100
        ),
        [0, 2],
    )
    validate_trajectories(m, [traj])


@pytest.mark.parametrize(
    ("kwargs", "pointer"),
    [
        ({"width": 0, "height": 3}, "/width"),
        ({"width": 3, "height": 2.5}, "/height"),
        ({"width": 3, "height": 3, "moves": 6}, "/moves"),
        ({"width": 3, "height": 3, "slip": 1.5}, "/slip"),
        ({"width": 3, "height": 3, "slip": float("nan")}, "/slip"),
        ({"width": 3, "height": 3, "velocity": True, "moves": 4}, "/moves"),
        ({"width": 3, "height": 3, "velocity": True, "stay": True}, "/stay"),
        ({"width": 100_000, "height": 100_000}, "/width"),
    ],
)
def test_bad_grid_arguments_name_the_field(kwargs: dict[str, object], pointer: str) -> None:
    with pytest.raises(InvalidInput) as exc:
        grid_mdp(gamma=0.9, **kwargs)  # type: ignore[arg-type]
    assert pointers(exc) == [pointer]
    assert str(exc.value)


def test_bad_gamma_is_reported_by_the_mdp_validation() -> None:
    with pytest.raises(InvalidInput) as exc:
        grid_mdp(width=3, height=3, gamma=1.0)
    assert pointers(exc) == ["/gamma"]
