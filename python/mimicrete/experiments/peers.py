"""``python -m mimicrete.experiments.peers``: LeRobot's ACT and Diffusion Policy on our demos,
evaluated in our env (issue 22, part 3: peers on the same demos), beside our learner and the
paper's recipe on the same demos (``--methods ours paper``, :mod:`.peers_ours`).

For each demo count N (the first N demos of ``--demos``, by file name) it

1. exports them with our exporter (:func:`mimicrete.export.export`, ``--format lerobot``) to
   ``OUT/datasets/suction-n<N>`` and adds the one feature LeRobot's ACT and Diffusion refuse to
   train without: ``observation.environment_state`` (both need an image or an environment
   state), the current frame's target and tile positions, copied from ``observation.state``
   (which stays the whole 5-frame observation the env gives). Its statistics, and those of
   ``observation.state``, get a floor (std >= 0.01, max - min >= 0.02; metres, radians): a
   feature that never varies in the demos (the target, the resting tile's height) has std 0,
   which LeRobot's normaliser divides by (plus 1e-8), so a target moved by 2 cm at test time
   would reach the network as 2e6. The action is the exporter's: the suction command as a level
   (``suction_level``, +1 / -1 held, docs/formats.md section 4), which the adapter maps back to
   the env's command; a dataset, a training or a result of the old layout (``suction_command``,
   the one-step switch) is not reused: an old dataset is refused naming its layout, an old
   training is redone, an old result evaluated again;
2. trains each method with lerobot's own training script (``lerobot.scripts.lerobot_train``) in
   the lerobot venv ``.venv-export`` (lerobot 0.4.4 and its torch; our venv's pins clash with
   them), CPU only, a fixed number of steps, one training at a time under ``nice``;
3. evaluates the final checkpoint in our env with :mod:`mimicrete.experiments.peer_adapter`, also
   in ``.venv-export``: it imports our ``mimicrete`` package from this checkout (the native module
   is built for CPython 3.11, which both venvs run; its import needs only numpy and gymnasium,
   which the lerobot venv has), loads the policy and its pre/post-processors with lerobot and
   steps :func:`mimicrete.envs.make_vec` itself. Deterministic (ACT without its VAE sampling at
   test time, as lerobot runs it; Diffusion from seeded noise), ``--episodes`` episodes split
   over the envs as ``mimicrete eval`` splits them, env seed = the training seed + 10,000;
4. writes ``OUT/results/<method>-n<N>-<starts>.json`` (installed / picked rates, mean length,
   training steps, wall clock and CPU seconds of the training and of the evaluation).

``report`` makes the Markdown table and the figure (success against demo count, one line per
method, one panel per start set) from those JSON files alone; with ``--into docs/RESULTS.md`` the
table replaces the one between the ``<!-- peers:table -->`` markers there.

Start sets (``--starts``): ``training`` (the env's own starts, as the demos were recorded),
``robust`` (``SimVecEnv.set_variation(robust=True)``: tile x in [-0.075, 0.225] m, target moved
by up to 2 cm) and ``wide`` (``set_variation(starts="wide")``, as ``mimicrete eval --starts wide``:
tile x in [0.035, 0.285] m, y in [0.26, 0.36] m, turned by up to 30 degrees, target and pad moved
by up to 4 cm).
Finished steps are not redone: a dataset, a training or a result that exists is reused (delete it
to redo it).
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from mimicrete.console import show_messages
from mimicrete.export import levels

from . import peers_ours
from .peers_report import FIGURE, STARTS, PeersError, report

# named, not __name__: run as `python -m`, this module is __main__, outside the package's logger
logger = logging.getLogger("mimicrete.experiments.peers")

REPO = Path(__file__).resolve().parents[3]
DEFAULT_LEROBOT_PYTHON = REPO / ".venv-export" / "bin" / "python"
#: LeRobot's learners (trained in the lerobot venv) and ours (:mod:`.peers_ours`, in this one)
LEROBOT_METHODS = ("act", "diffusion")
METHODS = (*LEROBOT_METHODS, "ours", "paper")

DEFAULT_COUNTS = (1, 5, 10, 20)
#: LeRobot's config overrides per method (everything else is lerobot 0.4.4's default). The
#: defaults are sized for a GPU (ACT's 40M parameters: about 2 CPU s per step at batch 8 here;
#: Diffusion's U-Net widths 512/1024/2048); on the CPU budget of this comparison both are made
#: smaller (7.5M and 5.0M parameters), ACT learns at Diffusion's rate (1e-4, not 1e-5) and
#: Diffusion samples with DDIM in 10 steps (not DDPM's 100).
POLICY_OVERRIDES: dict[str, list[str]] = {
    "act": [
        "--policy.dim_model=256",
        "--policy.dim_feedforward=1024",
        "--policy.chunk_size=20",
        "--policy.n_action_steps=20",
        "--policy.optimizer_lr=1e-4",
    ],
    "diffusion": [
        "--policy.down_dims=[64,128,256]",
        "--policy.noise_scheduler_type=DDIM",
        "--policy.num_inference_steps=10",
    ],
}
#: default training budget per method (steps at --batch-size)
DEFAULT_STEPS = {"act": 1000, "diffusion": 1000}
STAT_FLOOR = 0.01
ENV_STATE = "observation.environment_state"
#: the names (last frame of the stacked observation) copied into ENV_STATE
ENV_STATE_PREFIXES = ("t.target_", "t.tile_", "t.block_", "t.nut_")


# ------------------------------------------------------------------------------- the dataset


def first_demos(demos_dir: Path, n: int, out: Path) -> Path:
    """A folder ``out`` of symlinks to the first ``n`` ``*.mcap`` demos of ``demos_dir``."""
    from mimicrete.export.source import demo_files

    files = demo_files(demos_dir)
    if len(files) < n:
        raise PeersError(f"{demos_dir}: {len(files)} demos, {n} asked for (`make demos` makes 60)")
    out.mkdir(parents=True, exist_ok=True)
    for f in files[:n]:
        link = out / f.name
        if not link.exists():
            link.symlink_to(f.resolve())
    return out


def _floor_stats(st: dict[str, Any]) -> dict[str, Any]:
    out = dict(st)
    std = np.asarray(st["std"], dtype=np.float64)
    lo, hi = np.asarray(st["min"], np.float64), np.asarray(st["max"], np.float64)
    mid = (lo + hi) / 2
    narrow = hi - lo < 2 * STAT_FLOOR
    out["std"] = np.maximum(std, STAT_FLOOR).tolist()
    out["min"] = np.where(narrow, mid - STAT_FLOOR, lo).tolist()
    out["max"] = np.where(narrow, mid + STAT_FLOOR, hi).tolist()
    return out


def add_environment_state(root: Path) -> list[str]:
    """Add :data:`ENV_STATE` to the LeRobot dataset at ``root`` (data files, info.json,
    stats.json) and floor the state statistics; returns the copied names."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from mimicrete.export import lerobot as lr

    info_path, stats_path = root / "meta" / "info.json", root / "meta" / "stats.json"
    info = json.loads(info_path.read_text())
    names = info["features"]["observation.state"]["names"]
    cols = [i for i, nm in enumerate(names) if nm.startswith(ENV_STATE_PREFIXES)]
    if not cols:
        raise PeersError(f"{root}: no target or object position in observation.state")
    parts = []
    for f in sorted((root / "data").rglob("*.parquet")):
        table = pq.read_table(f)
        flat = table.column("observation.state").combine_chunks().flatten().to_numpy()
        state = flat.reshape(table.num_rows, len(names)).astype(np.float32)
        env = np.ascontiguousarray(state[:, cols])
        parts.append(env)
        arr = pa.FixedSizeListArray.from_arrays(pa.array(env.reshape(-1)), len(cols))
        pq.write_table(table.append_column(ENV_STATE, arr), f, compression="snappy")
    info["features"][ENV_STATE] = {
        "dtype": "float32",
        "shape": [len(cols)],
        "names": [names[i] for i in cols],
    }
    info_path.write_text(json.dumps(info, indent=4))
    stats = json.loads(stats_path.read_text())
    env_stats = {s: v.tolist() for s, v in lr._stats(np.concatenate(parts)).items()}
    stats[ENV_STATE] = _floor_stats(env_stats)
    stats["observation.state"] = _floor_stats(stats["observation.state"])
    stats_path.write_text(json.dumps(stats, indent=4))
    return [names[i] for i in cols]


def dataset_layout(root: Path) -> str:
    """The action layout of the LeRobot dataset at ``root`` (:func:`levels.layout_of`)."""
    info = json.loads((root / "meta" / "info.json").read_text())
    try:
        return levels.layout_of(info["features"]["action"]["names"])
    except (KeyError, ValueError) as e:
        raise PeersError(f"{root}: no action layout in meta/info.json ({e})") from None


def make_dataset(demos_dir: Path, n: int, out: Path) -> Path:
    """The first ``n`` demos as a LeRobot dataset at ``out/datasets/suction-n<n>`` (made once)."""
    from mimicrete.export import export

    root = out / "datasets" / f"suction-n{n}"
    if (root / "meta" / "info.json").exists():
        if dataset_layout(root) != levels.LEVEL_LAYOUT:
            raise PeersError(
                levels.old_layout_message(str(root))
                + f" (delete {root}: the trainings and results on it are then redone too)"
            )
        return root
    with tempfile.TemporaryDirectory(dir=out) as tmp:
        src = first_demos(demos_dir, n, Path(tmp) / "demos")
        part = Path(tmp) / "dataset"
        export(src, "lerobot", part)
        add_environment_state(part)
        root.parent.mkdir(parents=True, exist_ok=True)
        os.replace(part, root)
    return root


# ------------------------------------------------------------------------- lerobot subprocesses


def _child_env(threads: int) -> dict[str, str]:
    env = dict(os.environ)
    env.update(
        HF_HUB_OFFLINE="1",
        HF_DATASETS_OFFLINE="1",
        WANDB_MODE="disabled",
        OMP_NUM_THREADS=str(threads),
        MKL_NUM_THREADS=str(threads),
        CUDA_VISIBLE_DEVICES="",
        TOKENIZERS_PARALLELISM="false",
    )
    env.pop("PYTHONPATH", None)
    return env


def _run_child(cmd: list[str], log: Path, threads: int, nice: int) -> tuple[float, float]:
    """Run ``cmd`` (output to ``log``) → (wall seconds, CPU seconds of the child)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    full = (["nice", "-n", str(nice)] if nice else []) + cmd
    with log.open("w") as fh:
        rc = subprocess.run(full, stdout=fh, stderr=subprocess.STDOUT, env=_child_env(threads))
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if rc.returncode != 0:
        tail = log.read_text(errors="replace").strip().splitlines()[-1:] or ["(no output)"]
        raise PeersError(f"{cmd[1:3]} exited {rc.returncode}: {tail[0][:300]} (log: {log})")
    return wall, cpu


def train_cmd(
    python: Path, method: str, dataset: Path, out_dir: Path, steps: int, batch: int, seed: int
) -> list[str]:
    """lerobot's training script on ``dataset``: CPU, no env eval, one checkpoint at the end."""
    return [
        str(python),
        "-m",
        "lerobot.scripts.lerobot_train",
        f"--policy.type={method}",
        "--policy.device=cpu",
        "--policy.push_to_hub=false",
        f"--dataset.repo_id=local/{dataset.name}",
        f"--dataset.root={dataset}",
        f"--output_dir={out_dir}",
        f"--steps={steps}",
        f"--batch_size={batch}",
        "--num_workers=0",
        "--eval_freq=0",
        f"--save_freq={steps}",
        f"--log_freq={max(1, min(200, steps // 10))}",
        f"--seed={seed}",
        "--wandb.enable=false",
        *POLICY_OVERRIDES[method],
    ]


def checkpoint_of(train_dir: Path) -> Path:
    """The final ``pretrained_model`` folder of a lerobot training dir."""
    ck = train_dir / "checkpoints" / "last" / "pretrained_model"
    if not (ck / "config.json").exists():
        raise PeersError(f"{train_dir}: no finished checkpoint (checkpoints/last/pretrained_model)")
    return ck


def train(
    python: Path,
    method: str,
    dataset: Path,
    out: Path,
    n: int,
    steps: int,
    batch: int,
    seed: int,
    threads: int,
    nice: int,
) -> dict[str, Any]:
    """Train ``method`` on ``dataset`` into ``out/train/<method>-n<n>`` (once); its record."""
    train_dir = out / "train" / f"{method}-n{n}"
    record = train_dir.with_suffix(".json")
    layout = dataset_layout(dataset)
    if record.exists():
        rec = json.loads(record.read_text())
        same_data = rec.get("action_layout") == layout
        if same_data and rec.get("steps") == steps and rec.get("batch_size") == batch:
            return rec
    if train_dir.exists():  # an unfinished or other-budget training: lerobot wants a new dir
        shutil.rmtree(train_dir)
    train_dir.parent.mkdir(parents=True, exist_ok=True)
    log = train_dir.parent / f"{method}-n{n}.log"
    cmd = train_cmd(python, method, dataset, train_dir, steps, batch, seed)
    wall, cpu = _run_child(cmd, log, threads, nice)
    checkpoint_of(train_dir)
    rec = {
        "method": method,
        "demos": n,
        "steps": steps,
        "batch_size": batch,
        "epochs": round(steps * batch / _frames(dataset), 2),
        "frames": _frames(dataset),
        "seed": seed,
        "action_layout": layout,
        "threads": threads,
        "train_wall_s": round(wall, 1),
        "train_cpu_s": round(cpu, 1),
        "command": " ".join(cmd[1:]),
    }
    record.write_text(json.dumps(rec, indent=1))
    return rec


def _frames(dataset: Path) -> int:
    return int(json.loads((dataset / "meta" / "info.json").read_text())["total_frames"])


def evaluate(
    python: Path,
    checkpoint: Path,
    starts: list[str],
    episodes: int,
    seed: int,
    out_template: Path,
    threads: int,
    nice: int,
    max_envs: int = 25,
    max_steps: int | None = None,
) -> list[dict[str, Any]]:
    """The adapter (in the lerobot venv) on ``checkpoint``, one process for all ``starts``: a
    result dict per start set, written to ``out_template`` with ``{starts}`` filled in."""
    import mimicrete

    pkg_root = Path(mimicrete.__file__).resolve().parents[1]
    cmd = [
        str(python),
        str(Path(__file__).with_name("peer_adapter.py")),
        "--checkpoint",
        str(checkpoint),
        "--starts",
        *starts,
        "--episodes",
        str(episodes),
        "--seed",
        str(seed),
        "--max-envs",
        str(max_envs),
        "--mimicrete-path",
        str(pkg_root),
        "--out",
        str(out_template),
        *([] if max_steps is None else ["--max-steps", str(max_steps)]),
    ]
    log = Path(str(out_template).replace("{starts}", "eval")).with_suffix(".log")
    wall, cpu = _run_child(cmd, log, threads, nice)
    out = []
    for s in starts:
        res = json.loads(Path(str(out_template).replace("{starts}", s)).read_text())
        res["eval_wall_s"] = res.pop("eval_loop_s")
        res["eval_process_wall_s"], res["eval_process_cpu_s"] = round(wall, 1), round(cpu, 1)
        out.append(res)
    return out


# ------------------------------------------------------------------------------------ the grid


def result_path(out: Path, method: str, n: int, starts: str) -> Path:
    return out / "results" / f"{method}-n{n}-{starts}.json"


def run_grid(args: argparse.Namespace) -> list[Path]:
    """Every (count, method): dataset, training, evaluation on every start set (each once)."""
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    python = Path(args.lerobot_python)
    written = []
    for n in args.counts:
        if any(m in LEROBOT_METHODS for m in args.methods):
            dataset = make_dataset(Path(args.demos), n, out)
        for method in args.methods:
            if method not in LEROBOT_METHODS:
                written += _run_ours(args, method, n)
                continue
            steps = args.steps[method]
            rec = train(
                python, method, dataset, out, n, steps, args.batch_size, args.seed,
                args.threads, args.nice,
            )  # fmt: skip
            logger.info(
                f"{method} n={n}: {steps} steps ({rec['epochs']} epochs) in "
                f"{rec['train_wall_s']:.0f} s wall, {rec['train_cpu_s']:.0f} s CPU"
            )
            todo = []
            for starts in args.starts:
                path = result_path(out, method, n, starts)
                if _fresh(path, steps, args.episodes, layout=rec["action_layout"]):
                    written.append(path)
                else:
                    todo.append(starts)
            if not todo:
                continue
            template = result_path(out, method, n, "{starts}")
            template.parent.mkdir(parents=True, exist_ok=True)
            results = evaluate(
                python, checkpoint_of(out / "train" / f"{method}-n{n}"), todo, args.episodes,
                args.seed + 10_000, template, args.threads, args.nice,
                max_steps=args.eval_max_steps,
            )  # fmt: skip
            for starts, res in zip(todo, results, strict=True):
                res["eval_seed"] = res.pop("seed")
                res["lerobot"] = res.pop("lerobot_version", None)
                written.append(_write_result(result_path(out, method, n, starts), rec, res))
    return written


def _fresh(
    path: Path, steps: int, episodes: int, command: str | None = None, layout: str | None = None
) -> bool:
    """Whether the result at ``path`` exists for this training budget and episode count (and,
    given, the training ``command``: a training retrained another way is evaluated again; and the
    dataset's action ``layout``: a result of an old-layout training is evaluated again)."""
    old = json.loads(path.read_text()) if path.exists() else {}
    same = command is None or old.get("train_command") == command
    same = same and (layout is None or old.get("action_layout") == layout)
    return same and old.get("steps") == steps and old.get("episodes") == episodes


def _write_result(path: Path, rec: dict[str, Any], res: dict[str, Any]) -> Path:
    """One result file (written whole): the training's record, then the evaluation's ``res``."""
    from mimicrete.learn.run_files import atomic_write

    res = {**{k: v for k, v in rec.items() if k != "command"}, **res}
    res["train_command"] = rec["command"]
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, json.dumps(res, indent=1))
    logger.info(
        f"  {res['starts']}: installed {res['installed_rate']:.0%}, picked "
        f"{res['picked_rate']:.0%}, length {res['mean_episode_length']:.0f} "
        f"({res['episodes']} episodes, {res['eval_wall_s']:.0f} s)"
    )
    return path


def _run_ours(args: argparse.Namespace, method: str, n: int) -> list[Path]:
    """Our learner or the paper's recipe on the first ``n`` demos (:mod:`.peers_ours`)."""
    out = Path(args.out)
    demos = first_demos(Path(args.demos), n, out / "demos" / f"n{n}")
    steps = args.steps[method]
    rec = peers_ours.train(
        _run_child, method, demos, out, n, args.seed, REPO, steps, args.gen_count, args.nice,
        args.stop_on_convergence,
    )  # fmt: skip
    logger.info(
        f"{method} n={n}: {rec['steps']:,} env steps in {rec['train_wall_s']:.0f} s wall, "
        f"{rec['train_cpu_s']:.0f} s CPU"
    )
    written = []
    for starts in args.starts:
        path = result_path(out, method, n, starts)
        if not _fresh(path, rec["steps"], args.episodes, rec["command"]):
            res = peers_ours.evaluate(
                _run_child, out / "train" / f"{method}-n{n}", starts, args.episodes, args.nice
            )
            _write_result(path, rec, res)
        written.append(path)
    return written


# ---------------------------------------------------------------------------------- the report


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m mimicrete.experiments.peers",
        description="LeRobot's ACT and Diffusion Policy, our learner and the paper's recipe on "
        "the same first N demos, evaluated in our env on the same starts.",
    )
    sub = p.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run", help="export, train, evaluate (what exists is reused)")
    r.add_argument("--demos", default="demos/suction", help="MCAP demos (`make demos`)")
    r.add_argument("--counts", type=int, nargs="+", default=list(DEFAULT_COUNTS))
    r.add_argument("--methods", nargs="+", choices=METHODS, default=list(METHODS))
    r.add_argument("--starts", nargs="+", choices=STARTS, default=list(STARTS))
    r.add_argument("--act-steps", type=int, default=DEFAULT_STEPS["act"])
    r.add_argument("--diffusion-steps", type=int, default=DEFAULT_STEPS["diffusion"])
    r.add_argument("--batch-size", type=int, default=8, help="lerobot's default (8)")
    r.add_argument(
        "--our-steps",
        type=int,
        help="env steps of our learner (default: its config's, 2M for 1 demo, else 1M)",
    )
    r.add_argument(
        "--paper-steps",
        type=int,
        default=peers_ours.DEFAULT_PAPER_STEPS,
        help="env steps of the paper's recipe (group 4's config; 1M)",
    )
    r.add_argument(
        "--stop-on-convergence",
        action="store_true",
        help="our learner and the paper's recipe stop once training has converged (installed "
        ">= 99 %% in 3 summaries in a row, `mimicrete train --stop-on-convergence`); their "
        "step budgets become caps",
    )
    r.add_argument(
        "--gen-count",
        type=int,
        default=peers_ours.DEFAULT_GEN_COUNT,
        help="demos our learner generates from the N (mimicrete demogen; 500)",
    )
    r.add_argument("--episodes", type=int, default=100)
    r.add_argument(
        "--eval-max-steps",
        type=int,
        help="cut evaluation episodes after this many steps (smoke tests; default: the env's 750)",
    )
    r.add_argument("--seed", type=int, default=0, help="training seed; evaluation: + 10,000")
    r.add_argument("--threads", type=int, default=1, help="torch threads of each child (1)")
    r.add_argument("--nice", type=int, default=10)
    r.add_argument("--lerobot-python", default=str(DEFAULT_LEROBOT_PYTHON))
    r.add_argument("--out", default="runs/peers")
    rep = sub.add_parser("report", help="the table and the figure from OUT/results/*.json")
    rep.add_argument("--out", default="runs/peers", help="the run dir of `run`")
    rep.add_argument("--md", help="the table's file (default OUT/summary.md)")
    rep.add_argument("--figure", default=f"docs/figures/{FIGURE}")
    rep.add_argument("--into", help="also put the table between the markers of this file")
    return p


def main(argv: list[str] | None = None) -> int:
    """Exit 0; 2 with one line on bad input or a failed step."""
    args = build_parser().parse_args(argv)
    show_messages()

    def error(msg: str) -> int:
        print(f"peers: error: {msg}", file=sys.stderr)
        return 2

    try:
        if args.cmd == "report":
            md, fig = report(
                Path(args.out),
                Path(args.md) if args.md else None,
                Path(args.figure),
                Path(args.into) if args.into else None,
            )
            print(f"wrote {md} and {fig}" + (f"; table in {args.into}" if args.into else ""))
            return 0
        if any(n < 1 for n in args.counts) or args.episodes < 1 or args.batch_size < 1:
            return error("--counts, --episodes and --batch-size must be positive")
        if args.act_steps < 1 or args.diffusion_steps < 1 or args.threads < 1:
            return error("--act-steps, --diffusion-steps and --threads must be positive")
        if not Path(args.demos).is_dir():
            return error(f"{args.demos}: no such directory (`make demos` makes demos/suction)")
        for flag in ("our_steps", "paper_steps", "gen_count"):
            v = getattr(args, flag)
            if v is not None and v < 1:
                return error(f"--{flag.replace('_', '-')} must be positive, got {v}")
        lerobot = any(m in LEROBOT_METHODS for m in args.methods)
        if lerobot and not Path(args.lerobot_python).exists():
            return error(f"{args.lerobot_python}: no lerobot venv (`make export-venv` makes it)")
        args.steps = {
            "act": args.act_steps,
            "diffusion": args.diffusion_steps,
            "ours": args.our_steps,
            "paper": args.paper_steps,
        }
        run_grid(args)
        return 0
    except PeersError as e:
        return error(str(e))
    except (ValueError, OSError) as e:  # ExportError is a ValueError
        return error(str(e))
    except KeyboardInterrupt:
        print("peers: interrupted; finished steps are kept", file=sys.stderr)
        return 130


if __name__ == "__main__":
    raise SystemExit(main())
