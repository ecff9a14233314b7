"""What Duan & Zou report, for the comparison: Tables 3 and 5, the GAIL losses of §5.2, Fig. 7's
panels. Paper: *Learning from demonstrations: an intuitive VR environment for imitation learning of
construction robots*."""

from __future__ import annotations

PAPER_MAX_STEPS = 5_000_000
# Duan & Zou, Table 3 (algorithms with strengths, demonstrations).
PAPER_TABLE3: dict[int, tuple[str, str]] = {
    1: ("PPO", "-"),
    2: ("GAIL", "60"),
    3: ("PPO (1.0), GAIL (0.005), BC (0.5)", "60"),
    4: ("PPO (1.0), GAIL (0.01), BC (0.5)", "60"),
    5: ("PPO (1.0), GAIL (0.1), BC (0.5)", "60"),
    6: ("PPO (0.5), GAIL (0.5), BC (0.5)", "60"),
    7: ("PPO (0.1), GAIL (1.0), BC (0.5)", "60"),
    8: ("PPO (1.0), GAIL (0.01), BC (0.5)", "20"),
    9: ("PPO (1.0), GAIL (0.01), BC (0.5)", "10"),
}
# Duan & Zou, Table 5: picked rate, installed rate, average episode length (100 executions).
PAPER_TABLE5: dict[int, tuple[float, float, float]] = {
    1: (0.00, 0.00, 750.0),
    2: (0.18, 0.00, 750.0),
    3: (0.97, 0.97, 90.0),
    4: (0.97, 0.97, 173.0),
    5: (0.93, 0.00, 712.0),
    6: (0.02, 0.00, 737.0),
    7: (0.27, 0.00, 672.0),
    8: (0.00, 0.00, 750.0),
    9: (0.97, 0.82, 128.0),
}
# §5.2: "The average GAIL loss of group 2~4 for the last 100,000 steps are 0.73, 0.02, and 1.24".
PAPER_GAIL_LOSS = {2: 0.73, 3: 0.02, 4: 1.24}
# Fig. 7's panels as §5.1 assigns the groups: "Groups 1, 2, and 4 were applied to study the
# selection of RL methods. Groups 3~7 ... the relative strength ... Groups 4, 8, and 9 ... demos".
FIG7_PANELS: dict[str, tuple[str, list[int]]] = {
    "a": ("RL methods", [1, 2, 4]),
    "b": ("strength coefficients", [3, 4, 5, 6, 7]),
    "c": ("demonstration counts", [4, 8, 9]),
}
