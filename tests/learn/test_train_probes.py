"""Issue 24, items 9-14: `mimicrete train` probed through the real command line. Refused input is
one line naming the file and field, exit 2, and leaves nothing behind; a resumed run keeps what
shaped it; one trainer per run dir (a dead one's lock is taken over); every integer field has a
range; YAML is read within bounds; a full disk is said in words and leaves no partial file.

Most probes call ``mimicrete.cli.main`` in this process (the parser, the command and its error
handling, as the console script runs them); the ones about processes (a lock, a file-size
limit) run ``python -m mimicrete`` in a subprocess."""

from __future__ import annotations

import csv
import dataclasses
import errno
import os
import resource
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
import yaml

from mimicrete import cli
from mimicrete.learn import config, config_text
from mimicrete.testing.toyenv import toy_config

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from _cli_run import run_cli  # noqa: E402

MAX_LINE = 800  # what a one-line error may be at most (cli.MAX_MESSAGE plus the prefix)


@pytest.fixture(scope="module")
def toy_yaml(tmp_path_factory) -> Path:
    """The toy config of the trainer's tests (2048 steps, checkpoints every 1024), shared: no
    test changes it."""
    d = tmp_path_factory.mktemp("toy")
    path = d / "toy.yaml"
    config.save(toy_config(d, max_steps=2048, buffer=512, ckpt=1024), path)
    return path


def run(argv: list[str], capsys) -> tuple[int, str, str]:
    capsys.readouterr()
    rc = cli.main(argv)
    out, err = capsys.readouterr()
    return rc, out, err


def one_error_line(err: str, cmd: str = "train") -> str:
    lines = [ln for ln in err.strip().splitlines() if not ln.startswith("warning: ")]
    assert len(lines) == 1, err[:2000]
    assert lines[0].startswith(f"mimicrete {cmd}: error: "), lines[0][:2000]
    assert "Traceback" not in err
    assert len(lines[0]) <= MAX_LINE, len(lines[0])
    return lines[0]


def train_argv(cfg: Path, run_dir: Path, *extra: str) -> list[str]:
    return ["train", "--config", str(cfg), "--run-dir", str(run_dir), "--no-progress",
            "--eval-episodes", "0", *extra]  # fmt: skip


def steps_of(run_dir: Path) -> list[int]:
    with open(run_dir / "scalars.csv") as f:
        return [int(r["step"]) for r in csv.DictReader(f)]


def leftovers(d: Path) -> list[str]:
    """Temporary or lock files left anywhere under ``d``."""
    return sorted(
        str(p.relative_to(d))
        for p in d.rglob("*")
        if p.name.endswith((".tmp", ".partial", ".lock")) or ".tmp" in p.name
    )


# ----------------------------------------------------------------------------------------------
# 9. the demos are checked against the task, and a refused start leaves no run dir
# ----------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def grip_demos(tmp_path_factory) -> Path:
    """A BlockGrip demo made through the real path (synth-hands + convert)."""
    d = tmp_path_factory.mktemp("grip")
    r = run_cli("synth-hands", "--task", "grip", "--episodes", "1", "--out", str(d / "hands"))
    assert r.returncode == 0, r.stderr
    r = run_cli("convert", str(d / "hands"), "--task", "grip", "--out", str(d / "demos"),
                "--no-progress")  # fmt: skip
    assert r.returncode == 0, r.stderr
    return d / "demos"


SUCTION_SMALL = [
    "--set", "behavior.hyperparameters.buffer_size=256", "--set",
    "behavior.hyperparameters.batch_size=128", "--set", "behavior.network_settings.hidden_units=16",
    "--set", "behavior.demo_episodes=1", "--num-envs", "4",
]  # fmt: skip


def test_demos_of_another_task_are_refused_naming_a_file_and_the_tasks(
    grip_demos, tmp_path, capsys
):
    """BlockGrip demos have TileSuction's observation and action sizes: the sizes cannot tell,
    the demos' own task record does."""
    rd = tmp_path / "run"
    cfg = config.find_config_dir() / "group3.yaml"
    rc, _, err = run(train_argv(cfg, rd, "--demos", str(grip_demos), *SUCTION_SMALL), capsys)
    assert rc == 2
    line = one_error_line(err)
    assert "BlockGrip" in line and "TileSuction" in line and ".mcap" in line
    assert not rd.exists()


def test_a_refused_demo_path_leaves_no_run_dir(toy_yaml, tmp_path, capsys):
    rd = tmp_path / "runs" / "new"
    rc, _, err = run(train_argv(toy_yaml, rd, "--demos", str(tmp_path / "nope")), capsys)
    assert rc == 2
    assert "nope" in one_error_line(err)
    assert not rd.exists() and not rd.parent.exists()


def test_a_refused_demo_path_leaves_an_existing_run_as_it_was_even_with_force(
    trained, toy_yaml, tmp_path, capsys
):
    rd = trained
    before = sorted(p.name for p in rd.iterdir())
    rc, _, err = run(train_argv(toy_yaml, rd, "--force", "--demos", str(tmp_path / "x")), capsys)
    assert rc == 2
    one_error_line(err)
    assert sorted(p.name for p in rd.iterdir()) == before  # --force deleted nothing yet


# ----------------------------------------------------------------------------------------------
# 10. resume
# ----------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def trained_once(toy_yaml, tmp_path_factory) -> Path:
    rd = tmp_path_factory.mktemp("trained") / "run"
    assert cli.main(train_argv(toy_yaml, rd)) == 0
    assert [p.name for p in sorted((rd / "checkpoints").iterdir())] == [
        "step_000001024.pt",
        "step_000002048.pt",
    ]
    return rd


@pytest.fixture()
def trained(trained_once, tmp_path) -> Path:
    """A copy of a toy run of 2048 steps with checkpoints at 1024 and 2048."""
    rd = tmp_path / "run"
    shutil.copytree(trained_once, rd)
    return rd


@pytest.mark.parametrize(
    ("flags", "named"),
    [
        (["--set", "behavior.network_settings.hidden_units=64"],
         "behavior.network_settings.hidden_units 32 -> 64"),
        (["--seed", "5"], "env_settings.seed 0 -> 5"),
        (["--num-envs", "4"], "env_settings.num_envs 8 -> 4"),
        (["--set", "behavior.hyperparameters.learning_rate=0.1"],
         "behavior.hyperparameters.learning_rate 0.0005 -> 0.1"),
        (["--set", "behavior.reward_signals.gail.strength=0.5"],
         "behavior.reward_signals.gail.strength 0.01 -> 0.5"),
    ],
)  # fmt: skip
def test_resume_refuses_a_change_that_shapes_the_run_and_names_it(
    trained, toy_yaml, flags, named, capsys
):
    files = {p: p.read_bytes() for p in trained.rglob("*") if p.is_file()}
    rc, _, err = run(train_argv(toy_yaml, trained, "--resume", "--max-steps", "3072", *flags),
                     capsys)  # fmt: skip
    assert rc == 2
    line = one_error_line(err)
    assert named in line and "--resume" in line
    assert {p: p.read_bytes() for p in trained.rglob("*") if p.is_file()} == files


def test_resume_may_change_the_budget_and_the_threads(trained, toy_yaml, capsys):
    more = ["--set", "torch_settings.num_threads=2", "--set", "behavior.keep_checkpoints=4"]
    argv = train_argv(toy_yaml, trained, "--resume", "--max-steps", "3072", *more)
    assert run(argv, capsys)[0] == 0
    assert steps_of(trained) == [512, 1024, 1536, 2048, 2560, 3072]


def test_resume_without_config_continues_with_the_runs_own(trained, capsys):
    argv = ["train", "--run-dir", str(trained), "--resume", "--max-steps", "3072",
            "--no-progress", "--eval-episodes", "0"]  # fmt: skip
    rc, _, err = run(argv, capsys)
    assert rc == 0, err
    assert steps_of(trained) == [512, 1024, 1536, 2048, 2560, 3072]


def test_a_damaged_latest_checkpoint_is_named_and_the_previous_one_resumed(
    trained, toy_yaml, capsys
):
    (trained / "checkpoints" / "step_000002048.pt").write_text('{"not": "a checkpoint"}')
    rc, _, err = run(train_argv(toy_yaml, trained, "--resume", "--max-steps", "3072"), capsys)
    assert rc == 0, err
    assert "step_000002048.pt" in err and "damaged" in err and "step_000001024.pt" in err
    warned = [ln for ln in err.splitlines() if ln.startswith("warning: ")]  # the library's log
    assert len(warned) == 1 and "step_000002048.pt" in warned[0], err
    assert "Traceback" not in err
    assert steps_of(trained) == [512, 1024, 1536, 2048, 2560, 3072]
    # the step redone from 1024 rewrote the damaged checkpoint whole
    from mimicrete.learn import run_files

    assert run_files.load_checkpoint(trained / "checkpoints" / "step_000002048.pt")["step"] == 2048


def test_no_intact_checkpoint_is_one_line_naming_them(trained, toy_yaml, capsys):
    for p in (trained / "checkpoints").iterdir():
        p.write_bytes(p.read_bytes()[:1000])  # cut
    rc, _, err = run(train_argv(toy_yaml, trained, "--resume", "--max-steps", "3072"), capsys)
    assert rc == 2
    line = one_error_line(err)
    assert "step_000002048.pt" in line and "step_000001024.pt" in line and "intact" in line


# ----------------------------------------------------------------------------------------------
# 11. one trainer per run dir; a dead owner's lock is taken over
# ----------------------------------------------------------------------------------------------

HOLD = textwrap.dedent(
    """
    import sys
    from mimicrete.safe_io import FileLock
    FileLock(sys.argv[1], "test").acquire()
    print("held", flush=True)
    sys.stdin.read()
    """
)


def hold_lock(path: Path) -> subprocess.Popen:
    """Another process holding the lock file ``path`` until it is killed."""
    p = subprocess.Popen([sys.executable, "-c", HOLD, str(path)], stdin=subprocess.PIPE,
                         stdout=subprocess.PIPE, text=True)  # fmt: skip
    assert p.stdout is not None and p.stdout.readline().strip() == "held"
    return p


def test_a_run_dir_in_use_is_refused_and_a_killed_owners_lock_is_taken_over(
    toy_yaml, tmp_path, capsys
):
    rd = tmp_path / "run"
    rd.mkdir()
    holder = hold_lock(rd / ".lock")
    try:
        rc, _, err = run(train_argv(toy_yaml, rd, "--max-steps", "512"), capsys)
        assert rc == 2
        line = one_error_line(err)
        assert ".lock" in line and f"process {holder.pid}" in line
        assert sorted(p.name for p in rd.iterdir()) == [".lock"]
    finally:
        holder.send_signal(signal.SIGKILL)
        holder.wait()
    assert (rd / ".lock").exists()  # left behind by the killed owner
    rc, _, err = run(train_argv(toy_yaml, rd, "--max-steps", "512"), capsys)
    assert rc == 0, err
    assert not (rd / ".lock").exists()


def test_two_trainers_in_one_run_dir_at_once(toy_yaml, tmp_path, capsys):
    """The real race: a second ``mimicrete train`` starts while the first trains."""
    rd = tmp_path / "run"
    env = {**os.environ, "PYTHONPATH": str(Path(cli.__file__).parents[2])}
    first = subprocess.Popen(
        [sys.executable, "-m", "mimicrete", *train_argv(toy_yaml, rd, "--max-steps", "1024",
                                                       "--seed", "1")],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
    )  # fmt: skip
    deadline = time.monotonic() + 120
    while not (rd / ".lock").exists() and first.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    rc, _, err = run(train_argv(toy_yaml, rd, "--max-steps", "1024", "--seed", "2"), capsys)
    out, first_err = first.communicate(timeout=300)
    assert first.returncode == 0, first_err
    assert rc == 2, err
    assert f"in use by process {first.pid}" in one_error_line(err)
    assert steps_of(rd) == [512, 1024]
    assert config.load(rd / "resolved_config.yaml").env_settings.seed == 1


# ----------------------------------------------------------------------------------------------
# 12. every integer field has a range, named in the error
# ----------------------------------------------------------------------------------------------


def _int_fields() -> list[tuple[type, str, str]]:
    """(dataclass, field, dotted override key) of every integer field of the schema."""
    where = {
        config.Hyperparameters: "behavior.hyperparameters",
        config.NetworkSettings: "behavior.network_settings",
        config.BehavioralCloningSettings: "behavior.behavioral_cloning",
        config.DemoCurriculumSettings: "behavior.demo_curriculum",
        config.BehaviorConfig: "behavior",
        config.EnvSettings: "env_settings",
        config.TorchSettings: "torch_settings",
        config.ConvergenceSettings: "behavior.stop_on_convergence",
    }
    out = []
    for cls, prefix in where.items():
        for f in dataclasses.fields(cls):
            if str(f.type).startswith("int"):
                out.append((cls, f.name, f"{prefix}.{f.name}"))
    return out


INT_FIELDS = _int_fields()


def test_every_integer_field_of_the_schema_has_a_finite_range():
    assert len(INT_FIELDS) >= 24  # the 24 of the issue, and any added since
    for cls, name, key in INT_FIELDS:
        rng = config.RANGES.get((cls, name))
        assert rng is not None and rng.lo is not None and rng.hi is not None, key
        assert rng.hi <= 2**40, key  # fits every C++ integer torch and the simulator use


BAD_INTS = [".nan", ".inf", "-.inf", "18446744073709551617"]


@pytest.mark.parametrize("value", BAD_INTS)
@pytest.mark.parametrize("key", [k for _, _, k in INT_FIELDS])
def test_every_integer_field_refuses_nan_infinities_and_huge_values_naming_itself(
    toy_yaml, tmp_path, key, value, capsys
):
    rd = tmp_path / "run"
    rc, _, err = run(train_argv(toy_yaml, rd, "--set", f"{key}={value}"), capsys)
    assert rc == 2
    line = one_error_line(err)
    assert f"{key.split('.', 1)[-1]}: " in line and "out of range (allowed: " in line, line
    assert not rd.exists()


@pytest.mark.parametrize("key", ["behavior.network_settings.num_layers",
                                 "behavior.network_settings.hidden_units",
                                 "torch_settings.num_threads"])  # fmt: skip
def test_huge_network_sizes_are_refused_before_anything_is_built(toy_yaml, tmp_path, key):
    rd = tmp_path / "run"
    r = run_cli(*train_argv(toy_yaml, rd, "--set", f"{key}=18446744073709551617"), timeout=60)
    assert r.returncode == 2
    assert key.split(".")[-1] in one_error_line(r.stderr)
    assert not rd.exists()


def test_integer_fields_in_the_file_itself_are_checked_too(tmp_path, capsys):
    cfg = toy_config(tmp_path).to_dict()
    cfg["behaviors"]["Toy"]["network_settings"]["num_layers"] = float("nan")
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(cfg))
    rc, _, err = run(train_argv(path, tmp_path / "run"), capsys)
    assert rc == 2
    line = one_error_line(err)
    assert str(path) in line and "network_settings.num_layers: nan is out of range" in line


# ----------------------------------------------------------------------------------------------
# 13. YAML within bounds; the file and the field named
# ----------------------------------------------------------------------------------------------


def alias_bomb(depth: int) -> str:
    lines = ['a0: &a0 ["x", "x", "x", "x", "x", "x", "x", "x", "x"]']
    for i in range(1, depth + 1):
        lines.append(f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 9) + "]")
    return "\n".join(lines)


def config_with(tmp_path: Path, field_yaml: str, name: str = "bomb.yaml") -> Path:
    """The toy config with ``behavior.trainer_type`` set to the YAML value ``field_yaml`` (a
    node of its own, indented under the key)."""
    text = yaml.safe_dump(toy_config(tmp_path).to_dict(), sort_keys=False)
    body = textwrap.indent(field_yaml, "      ")
    text = text.replace("    trainer_type: ppo\n", f"    trainer_type:\n{body}\n", 1)
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.mark.parametrize("depth", [6, 8])
def test_an_alias_bomb_in_a_field_is_refused_quickly_in_one_short_line(tmp_path, depth, capsys):
    path = config_with(tmp_path, alias_bomb(depth))
    t0 = time.perf_counter()
    rc, _, err = run(train_argv(path, tmp_path / "run"), capsys)
    assert time.perf_counter() - t0 < 5
    assert rc == 2
    line = one_error_line(err)
    assert str(path) in line and "alias" in line


def test_an_alias_bomb_in_a_set_value_is_refused(toy_yaml, tmp_path, capsys):
    bomb = "{" + alias_bomb(8).replace("\n", ", ") + "}"
    argv = train_argv(toy_yaml, tmp_path / "run", "--set", f"behavior.trainer_type={bomb}")
    rc, _, err = run(argv, capsys)
    assert rc == 2
    assert "alias" in one_error_line(err)


def test_deep_nesting_is_refused_naming_the_file(tmp_path, capsys):
    path = config_with(tmp_path, "[" * 5000 + "]" * 5000)
    rc, _, err = run(train_argv(path, tmp_path / "run"), capsys)
    assert rc == 2
    line = one_error_line(err)
    assert str(path) in line and "nested more than" in line


def test_a_config_that_is_not_utf8_is_refused_naming_the_file_and_line(tmp_path, capsys):
    path = tmp_path / "latin1.yaml"
    text = yaml.safe_dump(toy_config(tmp_path).to_dict(), sort_keys=False)
    path.write_bytes(text.replace("trainer_type: ppo", "trainer_type: pp\xf6").encode("latin-1"))
    rc, _, err = run(train_argv(path, tmp_path / "run"), capsys)
    assert rc == 2
    line = one_error_line(err)
    assert str(path) in line and "not UTF-8" in line and "0xf6" in line


def test_a_huge_config_file_is_not_read_whole(tmp_path, capsys):
    path = tmp_path / "huge.yaml"
    path.write_text("# " + "x" * (config_text.MAX_CONFIG_BYTES + 10) + "\n")
    rc, _, err = run(train_argv(path, tmp_path / "run"), capsys)
    assert rc == 2
    assert str(path) in one_error_line(err)


@pytest.mark.parametrize(
    ("override", "named"),
    [
        ("behavior.reward_signals=null", "reward_signals: at least one of extrinsic, gail"),
        ("behavior.behavioral_cloning.demo_path=null", "demo_path: expected a string, got null"),
        ("behavior.max_steps=null", "max_steps: expected an integer, got null"),
        ("behavior.reward_signals.extrinsic.gamma=null", "gamma: expected a number, got null"),
        ("behavior.network_settings.normalize=null", "normalize: expected true/false, got null"),
        ("behavior.trainer_type=" + "x" * 100_000, "trainer_type: a string of 100000 characters"),
        ("behavior.no_such_key" + "y" * 100_000 + "=1", "unknown key(s)"),
    ],
)
def test_null_and_huge_values_are_one_short_line_naming_the_field(
    toy_yaml, tmp_path, override, named, capsys
):
    rc, _, err = run(train_argv(toy_yaml, tmp_path / "run", "--set", override), capsys)
    assert rc == 2
    line = one_error_line(err)
    assert named in line and str(toy_yaml) in line


# ----------------------------------------------------------------------------------------------
# 14. a full disk: said in words, and no file half written
# ----------------------------------------------------------------------------------------------


def _limit_file_size(limit: int):
    def set_limit() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails (EFBIG)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return set_limit


def test_a_checkpoint_past_the_file_size_limit_is_named_and_not_left_half_written(
    toy_yaml, tmp_path
):
    rd = tmp_path / "run"
    env = {**os.environ, "PYTHONPATH": str(Path(cli.__file__).parents[2])}
    r = subprocess.run(
        [sys.executable, "-m", "mimicrete", *train_argv(toy_yaml, rd, "--max-steps", "1024")],
        capture_output=True, text=True, env=env, timeout=300,
        preexec_fn=_limit_file_size(60_000),
    )  # fmt: skip
    assert r.returncode == 1, r.stderr
    line = one_error_line(r.stderr)
    assert "step_000001024.pt" in line and "file-size limit" in line
    assert "enforce fail" not in line and "unexpected pos" not in line
    assert not list((rd / "checkpoints").glob("*")), leftovers(rd)
    assert not (rd / "policy.pt").exists()
    assert leftovers(rd) == []


def test_a_full_disk_while_writing_policy_pt_leaves_no_policy_pt(
    toy_yaml, tmp_path, capsys, monkeypatch
):
    """Room for the checkpoints, not for ``policy.pt``: the write fails half way through with
    ENOSPC, as on a full disk."""
    real_write = os.write

    def write(fd: int, data) -> int:
        try:
            name = os.readlink(f"/proc/self/fd/{fd}")
        except OSError:
            name = ""
        if ".policy.pt." in name:
            if os.fstat(fd).st_size > 1000:
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            return real_write(fd, bytes(data)[:1000])
        return real_write(fd, data)

    monkeypatch.setattr(os, "write", write)
    rd = tmp_path / "run"
    rc, _, err = run(train_argv(toy_yaml, rd, "--max-steps", "1024"), capsys)
    assert rc == 1
    line = one_error_line(err)
    assert "policy.pt" in line and "disk is full" in line and "free" in line
    assert not (rd / "policy.pt").exists()
    assert [p.name for p in (rd / "checkpoints").iterdir()] == ["step_000001024.pt"]
    assert leftovers(rd) == []


def test_a_scalar_row_is_appended_whole_or_not_at_all(tmp_path, monkeypatch):
    from mimicrete import safe_io

    path = tmp_path / "scalars.csv"
    path.write_text("step,a\n1,2\n")
    real_write = os.write

    def half(fd: int, data) -> int:
        real_write(fd, bytes(data)[:3])
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(os, "write", half)
    with pytest.raises(safe_io.WriteError, match="disk is full"):
        safe_io.append_text(path, "2,3456789\n")
    monkeypatch.undo()
    assert path.read_text() == "step,a\n1,2\n"
