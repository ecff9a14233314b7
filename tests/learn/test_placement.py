"""`mimicrete eval`'s placement table through the real CLI: where each episode left the object
(held, height above rest, xy and yaw error, the lip-to-face gap of each hold) per episode and
summarised in eval.json and on the screen, checked against what the simulator says for the same
episodes; every eval variant has it, an env without the simulator has none."""

import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch
from tests._cli_run import run_cli

from mimicrete import _native
from mimicrete.learn.evaluate import summarise_placements
from mimicrete.learn.run_files import load_policy

POLICY = Path(__file__).parent / "data" / "group3_policy.pt"
MEASURES = ("height_above_rest", "xy_error", "yaw_error_deg")


def _run_dir(tmp_path: Path, name: str, policy: dict) -> Path:
    run = tmp_path / name
    run.mkdir()
    torch.save(policy, run / "policy.pt")
    return run


def _group3() -> dict:
    return torch.load(POLICY, weights_only=False)


def _does_nothing(env_id: str = "TileSuction-v0") -> dict:
    """The group-3 policy file with its heads zeroed: no joint moves, the command always 'hold'
    (index 1 of drop / hold / suction), so the object stays where it started. BlockGrip's
    observation and action have TileSuction's sizes, so it runs there too."""
    p = _group3()
    a = p["actor"]
    for k in ("mu.weight", "mu.bias", "logits.weight"):
        a[k] = torch.zeros_like(a[k])
    a["logits.bias"] = torch.tensor([0.0, 1.0, 0.0])
    p["config"]["env_settings"]["env_id"] = env_id
    return p


def _eval(run: Path, *flags: str) -> tuple[str, dict]:
    r = run_cli("eval", str(run), *flags)
    assert r.returncode == 0, r.stderr
    out = sorted(run.glob("eval*.json"), key=lambda f: f.stat().st_mtime)[-1]
    return r.stdout, json.loads(out.read_text())


def _check_summary(res: dict) -> None:
    """eval.json's ``placement`` is the summary of its own per-episode placements: shares,
    medians and worst (the value of the largest |value|), and the TilePlace rule's tolerances."""
    eps = [e["placement"] for e in res["per_episode"]]
    s = res["placement"]
    assert s == summarise_placements(eps)
    assert s["episodes"] == res["episodes"] == len(eps)
    th = _native.task_spec("TilePlace")["thresholds"]
    assert s["placed_rule"] == pytest.approx(
        {k: th[k] for k in ("rest_height", "success_dist", "success_yaw_deg")}
    )
    assert s["held_share"] == pytest.approx(np.mean([p["held"] for p in eps]))
    for k in MEASURES:
        v = np.array([p[k] for p in eps])
        assert s[k]["median"] == pytest.approx(np.median(v))
        assert abs(s[k]["worst"]) == pytest.approx(np.abs(v).max())
        assert s[k]["worst"] in v


def _stepped_by_hand(run: Path, seed: int) -> dict:
    """The placement the simulator gives at the end of episode ``seed`` of the run's
    deterministic policy, stepped in one plain ``SimEnv`` (the eval's env 0 plays that seed)."""
    actor, cfg = load_policy(run)
    env = _native.SimEnv(cfg.env_settings.env_id.removesuffix("-v0"), 0)
    obs = env.reset(seed)
    with torch.no_grad():
        while True:
            act = actor.deterministic(torch.from_numpy(obs[None]))[0].numpy()
            obs, _, term, trunc, _ = env.step(act)
            if term or trunc:
                return env.last_placement()


def test_group3_installs_held_and_no_install_is_placed(tmp_path):
    run = _run_dir(tmp_path, "run", _group3())
    out, res = _eval(run, "--episodes", "4")
    assert "placement (4 episodes)" in out and "worst: the largest |value|" in out
    for row in (
        "height above rest at the end [mm]",
        "xy error at the end [mm]",
        "yaw error at the end [deg]",
        "lip-to-face gap at each hold [mm]",
    ):
        assert row in out
    held = next(line for line in out.splitlines() if line.startswith("held at the end"))
    placed = next(line for line in out.splitlines() if line.startswith("placed by the placed"))
    assert held.split()[-1] == "100%"
    assert placed.split()[5] == "0%"
    assert "|height| <= 2 mm, xy <= 5 mm, |yaw| <= 2 deg" in placed
    _check_summary(res)
    # the paper's rule installs with the tile still on the cups: every episode ends held, so
    # none is placed; each began one hold, its gap recorded
    s = res["placement"]
    assert (s["held_share"], s["placed_share"]) == (1.0, 0.0)
    assert res["installed_rate"] == 1.0
    assert all(len(e["placement"]["hold_gaps"]) >= 1 for e in res["per_episode"])
    assert s["holds"] == sum(len(e["placement"]["hold_gaps"]) for e in res["per_episode"])
    # the table's millimetres are eval.json's metres
    xy = next(line for line in out.splitlines() if line.startswith("xy error"))
    assert float(xy.split()[-2]) == pytest.approx(s["xy_error"]["median"] * 1e3, abs=0.05)
    # one episode: what the simulator says stepping the same policy by hand in one env
    _, one = _eval(run, "--episodes", "1", "--seed", "123")
    want = _stepped_by_hand(run, 123)
    got = one["per_episode"][0]["placement"]
    assert got["held"] == want["held"]
    for k in MEASURES:
        assert got[k] == pytest.approx(want[k], abs=1e-5)
    assert got["hold_gaps"] == pytest.approx(want["hold_gaps"], abs=1e-5)


@pytest.mark.parametrize("starts", ["training", "wide"])
def test_a_policy_that_does_nothing_leaves_the_tile_where_it_started(tmp_path, starts):
    run = _run_dir(tmp_path, "still", _does_nothing())
    _, res = _eval(run, "--episodes", "2", "--starts", starts)
    _check_summary(res)
    target_xy = np.array(_native.task_spec("TileSuction")["target"]["xy"])
    for e in res["per_episode"]:
        p = e["placement"]
        assert e["length"] == 750 and not e["picked"]
        x, y, yaw = e["object_pose"]
        target = target_xy + np.array(e["target_offset"])
        assert p["xy_error"] == pytest.approx(math.dist((x, y), target), abs=1e-3)
        assert p["yaw_error_deg"] == pytest.approx(-math.degrees(yaw), abs=0.1)
        assert not p["held"] and p["hold_gaps"] == []
        # what the simulator says at that start before any step
        sim = _native.SimEnv("TileSuction", 0)
        sim.reset(0, object_pose=e["object_pose"], target_offset=e["target_offset"])
        at_start = sim.placement()
        for k, tol in zip(MEASURES, (1e-3, 1e-3, 0.1), strict=True):  # m, m, deg
            assert p[k] == pytest.approx(at_start[k], abs=tol)
    s = res["placement"]
    assert (s["held_share"], s["placed_share"], s["hold_gaps"], s["holds"]) == (0, 0, None, 0)


def test_every_eval_variant_keeps_the_placements(tmp_path):
    run = _run_dir(tmp_path, "run", _group3())
    f = tmp_path / "site.jsonl"
    f.write_text('{"object_pose": [0.05, 0.32, 0.0]}\n{"object_pose": [0.12, 0.33, 0.1]}\n')
    for flags, file in (
        (["--stochastic"], "eval_stochastic.json"),
        (["--starts", "robust"], "eval_robust.json"),
        (["--robust", "--stochastic"], "eval_robust_stochastic.json"),
        (["--starts", "wide"], "eval_wide.json"),
        (["--starts", str(f)], "eval_starts-site.json"),
    ):
        r = run_cli("eval", str(run), "--episodes", "2", *flags)
        assert r.returncode == 0, r.stderr
        assert "placed by the placed rule" in r.stdout
        res = json.loads((run / file).read_text())
        assert res["episodes"] == 2
        _check_summary(res)


def test_a_gripper_has_no_hold_gaps(tmp_path):
    run = _run_dir(tmp_path, "grip", _does_nothing("BlockGrip-v0"))
    out, res = _eval(run, "--episodes", "2")
    _check_summary(res)
    assert res["placement"]["hold_gaps"] is None
    gap = next(line for line in out.splitlines() if line.startswith("lip-to-face gap"))
    assert gap.split()[-3:] == ["(no", "suction", "holds)"]


def test_no_placement_off_the_simulator_or_for_screw(tmp_path):
    from mimicrete import tasks
    from mimicrete.learn.networks import Actor
    from mimicrete.testing import toyenv

    torch.manual_seed(0)
    toy_cfg = toyenv.toy_config(tmp_path)
    toy_obs = int(toyenv.make_vec(1).single_observation_space.shape[0])
    toy = Actor(toy_obs, 6, 32, 2, True, 1)
    screw_cfg = _group3()["config"]
    screw_cfg["env_settings"]["env_id"] = "Screw-v0"
    screw_obs = int(tasks.get("Screw").obs_dim)
    screw = Actor(screw_obs, 6, 256, 3, True, 2)
    for name, actor, obs_dim, cfg in (
        ("toy", toy, toy_obs, toy_cfg.to_dict()),
        ("screw", screw, screw_obs, screw_cfg),
    ):
        policy = {"actor": actor.state_dict(), "obs_dim": obs_dim, "step": 0, "config": cfg}
        run = _run_dir(tmp_path, name, policy)
        out, res = _eval(run, "--episodes", "2")
        assert "Installed rate" in out and "placement (" not in out and "placed by" not in out
        assert "placement" not in res
        assert all("placement" not in e for e in res["per_episode"])


def test_a_rate_short_of_whole_is_printed_to_a_tenth_never_rounded_to_100():
    from mimicrete.learn.evaluate import format_rows, percent

    assert [percent(x) for x in (1.0, 0.995, 0.97, 0.955, 0.0, 1 / 3)] == [
        "100%", "99.5%", "97%", "95.5%", "0%", "33.3%"
    ]  # fmt: skip
    row = format_rows([("run", {"picked_rate": 1.0, "installed_rate": 0.995,
                                "mean_episode_length": 106.3})])  # fmt: skip
    assert row.splitlines()[1].split() == ["run", "100%", "99.5%", "106.3"]


def test_success_is_called_placed_where_the_spec_judges_by_the_placed_rule():
    from mimicrete.learn.evaluate import success_word

    assert success_word("TilePlace-v0") == "placed"
    assert success_word("TileSuction-v0") == "installed"
    assert success_word("BlockGrip-v0") == "installed"
