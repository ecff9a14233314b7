"""No-op filtering of demonstrations (``behaviors.<name>.demo_drop_idle``): which steps leave."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from mimicrete.learn.demo_data import drop_idle_steps, idle_steps


def _acts(rows):
    return np.asarray(rows, np.float32)


def test_pauses_leave_motion_and_commands_stay():
    a = _acts(
        [
            [0.50, 0, 0, 0, 0, 0, -1],  # episode 0, first step: a command with no previous one
            [0.02, 0.01, 0, 0, 0, -0.05, -1],  # pause, command repeated -> idle
            [0.02, 0, 0, 0, 0, 0, 1],  # pause in the joints but the suction switches -> kept
            [0.00, 0, 0, 0, 0, 0, 1],  # pause, repeated +1 -> idle
            [0.00, 0, 0, 0, 0, 0.3, 1],  # one joint moves -> kept
            [0.00, 0, 0, 0, 0, 0, 0],  # "fixed" command, no motion -> idle
            [0.00, 0, 0, 0, 0, 0, 1],  # episode 1 starts: +1 with no previous -> kept
            [0.09, 0.09, 0, 0, 0, 0, 1],  # below 0.1 -> idle
            [0.10, 0, 0, 0, 0, 0, 1],  # at the threshold -> kept
        ]
    )
    ep = np.array([0, 0, 0, 0, 0, 0, 1, 1, 1])
    idle = idle_steps(a, ep, 0.1)
    assert idle.tolist() == [False, True, False, True, False, True, False, True, False]
    assert not idle_steps(a, ep, 0.0).any()

    d = {"obs": np.arange(9.0)[:, None], "actions": a, "episode": ep}
    kept = drop_idle_steps(d, 0.1)
    assert kept["obs"][:, 0].tolist() == [0, 2, 4, 6, 8]  # each kept action keeps its own obs
    assert np.array_equal(kept["actions"], a[~idle])


def test_screw_spin_is_work_while_it_turns():
    """The end-effector command is a latch (a repeat changes nothing), the spin turns the nut
    every step it is not 0: a still hand that keeps tightening is screwing, not pausing."""
    a = _acts(
        [
            [0, 0, 0, 0, 0, 0, 1, 0],  # grip closes (first step) -> kept
            [0, 0, 0, 0, 0, 0, 1, 1],  # still, tightening -> kept
            [0, 0, 0, 0, 0, 0, 1, 1],  # still, still tightening -> kept
            [0, 0, 0, 0, 0, 0, 1, -1],  # still, loosening -> kept
            [0, 0, 0, 0, 0, 0, 1, 0],  # still, grip held, spin stopped -> idle
            [0, 0, 0, 0, 0, 0, -1, 0],  # the grip opens -> kept
        ]
    )
    assert idle_steps(a, np.zeros(6, int), 0.1).tolist() == [False] * 4 + [True, False]


@settings(max_examples=200, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.lists(st.floats(-1, 1, width=32), min_size=6, max_size=6),
            st.sampled_from([-1.0, 0.0, 1.0]),
            st.booleans(),
        ),
        min_size=1,
        max_size=40,
    ),
    st.floats(0.0, 0.99),
)
def test_only_still_unchanging_steps_leave(rows, threshold):
    a = _acts([[*j, c] for j, c, _ in rows])
    ep = np.cumsum([new for _, _, new in rows])
    idle = idle_steps(a, ep, threshold)
    for i in np.flatnonzero(idle):
        assert np.abs(a[i, :6]).max() < threshold
        same_episode = i > 0 and ep[i - 1] == ep[i]
        assert a[i, 6] == 0 or (same_episode and a[i - 1, 6] == a[i, 6])
    for i in np.flatnonzero(~idle):  # kept: it moved, or its command changed something
        moved = np.abs(a[i, :6]).max() >= threshold
        first = i == 0 or ep[i - 1] != ep[i]
        changed = a[i, 6] != 0 and (first or a[i - 1, 6] != a[i, 6])
        assert threshold <= 0 or moved or changed
