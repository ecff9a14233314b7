"""A per-demonstration reverse curriculum (the reverse half of RFCL, Tao et al., ICLR 2024), for
learning from a handful of demos with the sparse reward (``behaviors.<name>.demo_curriculum``, a
mimicrete extension; ``configs/fewdemo.yaml``).

With few demos, BC alone does not install (10 demos: 0 % picked deterministically) and PPO from
the env's start rarely sees the +1 of an install, so it has nothing to climb. Here some episodes
start *inside* a demo instead: env i is reset to the demo's episode seed and the demo's first
``s`` recorded actions are replayed in it (``VecEnv.reset_replay``; the simulator is
deterministic, so this is exactly the state the demonstrator was in after ``s`` steps, frame stack
included). Each demo ``d`` has its own start ``s_d``, first one reverse step before its end (the
tile carried over the pad: the install is a few actions away); when the policy installs in at
least ``threshold`` of the last ``window`` episodes started at ``s_d``, ``s_d`` moves back one
reverse step (``step_fraction`` of the demo's length). A demo whose start reached 0 is *solved*
and its resets go back to the env's own starts. While any demo is unsolved, a reset starts from
an unsolved demo with probability ``reset_prob`` (uniformly among them), at its current start or,
with probability ``old_start_prob``, at one of the later starts it already passed (Florensa et
al.'s replay of old starts: the install reward keeps flowing while the frontier is hard, and what
was learnt there is not forgotten; only frontier episodes move the start); otherwise, and always
once all are solved, from the env's own random start: the evaluation's distribution, which is the
forward half (with one randomised coordinate, the tile's x, uniform starts are what RFCL's
forward curriculum converges to).

An episode started inside a demo is cut (a truncation: bootstrapped, not a failure) after
``horizon_ratio`` × the demo's remaining steps + ``min_horizon`` steps, as RFCL bounds its demo
episodes, so a stuck policy does not spend 700 steps there. Those episodes are counted apart
(``Curriculum/...`` scalars) so that ``Environment/Installed Rate`` stays the rate from the env's
own starts, the one the evaluation measures. Nothing here is read at test time: evaluation and
the exported policy see only observations.

**Forward curriculum** (``forward_to: wide``; RFCL's forward half). Demos are recorded where a
person records them, at the paper's starts; a policy should work wherever the tile lies. Once
every demo is solved, the env's own starts widen step by step from the paper's (scale 0) to the
wide ones (scale 1, tile-sim's ``Variation::towards_wide``): when at least ``forward_threshold``
of the last ``forward_window`` episodes from the env's own starts installed, the scale grows by
``forward_step``. The episodes the scale is judged on started after it was set.
``Curriculum/Forward Scale`` logs it.

**Pooled stages** (``pooled: true``, for many generated demos). Each demo walking back on its own
needs ``window`` frontier episodes per step per demo, so a curriculum over 500 generated demos
would never finish, and one over a handful teaches the place at a handful of targets only
(BlockGrip, ``max_demos: 5``: the block is set down where those 5 demos' targets were, 3-8 cm from
a moved one). Pooled, all demos share one stage (the same reverse step of each demo's own
schedule) and one judging window: a curriculum reset draws any unsolved demo, and the stage moves
back for all of them once ``threshold`` of the last ``window`` frontier episodes, whichever demos
they came from, succeeded. Off (the default), every demo has its own stage, as before.

Replayed steps are simulator work but not agent steps: they are not in the rollout and do not
count towards ``max_steps`` (RFCL sets states directly); ``Curriculum/Replayed Steps`` logs them.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np

from mimicrete.demos import recorded_start

from .config import DemoCurriculumSettings
from .demo_data import LoadedDemos


@dataclass(frozen=True)
class DemoTrack:
    """One demo as a sequence of reachable states: its episode seed and every recorded action."""

    seed: int
    actions: np.ndarray  # (L, act_dim) float32, idle steps included (replay needs them all)
    #: an explicit start (``object_pose``, ``target_offset``, a turned pad's ``pad_yaw``: a
    #: generated demo's, ``mimicrete demogen``), replayed there instead of at the paper's start
    #: of ``seed``
    start: dict[str, list[float]] | None = None

    @property
    def length(self) -> int:
        return int(len(self.actions))


def demo_tracks(demos: LoadedDemos) -> list[DemoTrack]:
    """The demos as the trainer read them (:func:`demo_data.read_demos`), as :class:`DemoTrack`:
    each episode's seed (from its file's ``episode`` metadata) and every recorded action, idle
    steps included, in the order of the trainer's demo arrays."""
    ep = np.asarray(demos.arrays["episode"])
    tracks = []
    for e in np.unique(ep):
        meta = demos.metas[e] if e < len(demos.metas) else {}
        if "seed" not in meta:
            where = demos.tasks[e][0] if e < len(demos.tasks) else f"demo episode {e}"
            raise ValueError(f"{where}: no episode seed in its metadata; cannot replay it")
        acts = np.asarray(demos.arrays["actions"][ep == e], np.float32)
        if len(acts) < 2:
            continue
        tracks.append(DemoTrack(int(meta["seed"]), acts, recorded_start(meta)))
    if not tracks:
        raise ValueError("no demo to start a curriculum from")
    return tracks


def start_schedule(length: int, step_fraction: float) -> list[int]:
    """The starts a demo of ``length`` steps goes through, latest first: one reverse step before
    its end, then back one step at a time, ending at 0. The last recorded action (the install)
    is never replayed, so every start leaves the agent at least one action to do."""
    step = max(1, round(step_fraction * length))
    first = max(0, length - step)
    starts = list(range(first, 0, -step))
    return [*starts, 0]


class ReverseCurriculum:
    """Per-demo start indices, their success windows, and the per-env bookkeeping of which
    running episode started where."""

    def __init__(
        self,
        tracks: list[DemoTrack],
        settings: DemoCurriculumSettings,
        num_envs: int,
        rng: np.random.Generator,
    ):
        self.tracks = tracks
        self.s = settings
        self.rng = rng
        self.schedules = [start_schedule(t.length, settings.step_fraction) for t in tracks]
        self.stage = [0] * len(tracks)  # index into each schedule
        self.results: list[deque[bool]] = [deque(maxlen=settings.window) for _ in tracks]
        self.pool_results: deque[bool] = deque(maxlen=settings.window)  # pooled: the shared one
        self.env_demo = np.full(num_envs, -1, np.int64)  # demo of each running episode, -1: own
        self.env_steps = np.zeros(num_envs, np.int64)
        self.env_horizon = np.zeros(num_envs, np.int64)
        self.env_frontier = np.zeros(num_envs, bool)  # started at its demo's current start
        self.replayed_steps = 0
        self.episodes_done: list[bool] = []  # curriculum episodes finished since the last summary
        # how far the env's own starts have widened (forward_to); forward_start: from the outset
        self.forward_scale = float(settings.forward_start)
        self.forward_results: deque[bool] = deque(maxlen=settings.forward_window)
        self.env_scale = np.zeros(
            num_envs
        )  # the scale each env's running own-start episode began at
        self._applied_scale: float | None = None  # the scale last set on the env (None: not yet)

    # -- state of the curriculum -------------------------------------------------------------

    def start(self, d: int) -> int:
        return self.schedules[d][self.stage[d]]

    def solved(self, d: int) -> bool:
        return self.stage[d] >= len(self.schedules[d])

    @property
    def unsolved(self) -> list[int]:
        return [d for d in range(len(self.tracks)) if not self.solved(d)]

    def progress(self) -> float:
        """Mean over demos of how far back the start has moved (0 = at the end, 1 = solved)."""
        return float(
            np.mean(
                [
                    min(st, len(sc)) / len(sc)
                    for st, sc in zip(self.stage, self.schedules, strict=True)
                ]
            )
        )

    def record(self, d: int, installed: bool, frontier: bool = True) -> None:
        """An episode started in demo ``d`` ended; if it started at the current start
        (``frontier``), move the start back once the window holds enough installs."""
        if not frontier:
            self.episodes_done.append(bool(installed))
            return
        if self.solved(d):
            return
        res = self.pool_results if self.s.pooled else self.results[d]
        res.append(bool(installed))
        self.episodes_done.append(bool(installed))
        if len(res) == res.maxlen and np.mean(res) >= self.s.threshold:
            for e in self.unsolved if self.s.pooled else [d]:
                self.stage[e] += 1
            res.clear()

    def record_own(self, i: int, installed: bool) -> None:
        """An episode of env ``i`` from the env's own start ended: judge the forward scale on it
        (if it started at the current scale and every demo is solved)."""
        if self.s.forward_to is None or self.unsolved or self.forward_scale >= 1.0:
            return
        if self.env_scale[i] != self.forward_scale:
            return
        res = self.forward_results
        res.append(bool(installed))
        if len(res) == res.maxlen and np.mean(res) >= self.s.forward_threshold:
            self.forward_scale = min(1.0, round(self.forward_scale + self.s.forward_step, 6))
            res.clear()

    def _apply_scale(self, env: Any) -> None:
        """Set the env's start variation to the forward scale, when it changed."""
        if self.s.forward_to is None or self._applied_scale == self.forward_scale:
            return
        env.sim.set_variation(towards_wide=self.forward_scale)
        self._applied_scale = self.forward_scale

    # -- per env ------------------------------------------------------------------------------

    def forget_envs(self) -> None:
        """Every env was reset to its own start (checkpoint boundary)."""
        self.env_demo[:] = -1
        self.env_steps[:] = 0

    def over_horizon(self, ended: np.ndarray) -> np.ndarray:
        """Count one step of every env; the envs on a demo start that ran past their horizon
        and did not end by themselves (to be cut as truncations)."""
        self.env_steps += 1
        return (self.env_demo >= 0) & (self.env_steps >= self.env_horizon) & ~ended

    def choose(self) -> int:
        """Demo index to start the next episode from, or -1 for the env's own start."""
        open_ = self.unsolved
        if not open_ or self.rng.random() >= self.s.reset_prob:
            return -1
        return int(open_[self.rng.integers(len(open_))])

    def restart(self, env: Any, ended: np.ndarray, need_reset: np.ndarray, obs: np.ndarray) -> None:
        """Start the next episode of every ``ended`` env: from a demo (replayed; ``obs`` row
        replaced) or from the env's own start (already auto-reset, unless ``need_reset``: then
        reset through the reset mask). ``obs`` is updated in place. With a forward curriculum, an
        auto-reset episode that began before the scale last grew is restarted at the new scale."""
        before = self._applied_scale
        self._apply_scale(env)
        rescale = before is not None and before != self._applied_scale
        own_reset = np.zeros(len(ended), bool)
        for i in np.flatnonzero(ended):
            d = self.choose()
            self.env_steps[i] = 0
            self.env_demo[i] = d
            if d < 0:
                own_reset[i] = need_reset[i] or rescale
                self.env_scale[i] = self.forward_scale
                continue
            tr, s = self.tracks[d], self.start(d)
            self.env_frontier[i] = True
            if self.stage[d] > 0 and self.rng.random() < self.s.old_start_prob:
                s = self.schedules[d][int(self.rng.integers(self.stage[d]))]  # a passed start
                self.env_frontier[i] = False
            extra = () if tr.start is None else (tr.start,)  # an explicit (generated) start
            obs[i] = env.reset_replay(int(i), tr.seed, tr.actions[:s], *extra)
            self.replayed_steps += s
            self.env_horizon[i] = int(self.s.horizon_ratio * (tr.length - s)) + self.s.min_horizon
        if own_reset.any():
            fresh, _ = env.reset(options={"reset_mask": own_reset})
            obs[own_reset] = np.asarray(fresh, np.float32)[own_reset]

    # -- log and resume -----------------------------------------------------------------------

    def summary(self) -> dict[str, float]:
        row = {
            "Curriculum/Progress": self.progress(),
            "Curriculum/Demos Solved": float(len(self.tracks) - len(self.unsolved)),
            "Curriculum/Replayed Steps": float(self.replayed_steps),
        }
        if self.s.forward_to is not None:
            row["Curriculum/Forward Scale"] = self.forward_scale
        if self.episodes_done:
            row["Curriculum/Installed Rate"] = float(np.mean(self.episodes_done))
            row["Curriculum/Episodes"] = float(len(self.episodes_done))
        self.episodes_done = []
        return row

    def state_dict(self) -> dict[str, Any]:
        """The stages, the judging windows, the random stream and which demo start each env's
        running episode came from (the envs themselves are in the vector env's ``state()``)."""
        return {
            "stage": list(self.stage),
            "results": [list(r) for r in self.results],
            **({"pool_results": list(self.pool_results)} if self.s.pooled else {}),
            "replayed_steps": self.replayed_steps,
            "rng": self.rng.bit_generator.state,
            "env_demo": self.env_demo.copy(),
            "env_steps": self.env_steps.copy(),
            "env_horizon": self.env_horizon.copy(),
            "env_frontier": self.env_frontier.copy(),
            "episodes_done": list(self.episodes_done),
            "forward_scale": self.forward_scale,
            "forward_results": list(self.forward_results),
            "env_scale": self.env_scale.copy(),
        }

    def load_state_dict(self, s: dict[str, Any]) -> None:
        self.stage = [int(x) for x in s["stage"]]
        for r, saved in zip(self.results, s["results"], strict=True):
            r.clear()
            r.extend(bool(x) for x in saved)
        self.pool_results.clear()
        self.pool_results.extend(bool(x) for x in s.get("pool_results", []))
        self.replayed_steps = int(s["replayed_steps"])
        self.rng.bit_generator.state = s["rng"]
        if "env_demo" not in s:  # an older checkpoint: its envs restart from their own starts
            self.forget_envs()
            return
        self.env_demo[:] = s["env_demo"]
        self.env_steps[:] = s["env_steps"]
        self.env_horizon[:] = s["env_horizon"]
        self.env_frontier[:] = s["env_frontier"]
        self.episodes_done = [bool(x) for x in s["episodes_done"]]
        self.forward_scale = float(s.get("forward_scale", 0.0))
        self.forward_results.clear()
        self.forward_results.extend(bool(x) for x in s.get("forward_results", []))
        if "env_scale" in s:
            self.env_scale[:] = s["env_scale"]
        self._applied_scale = None  # the restored env draws from the paper's starts: set it again
