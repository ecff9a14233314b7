"""Trainer configuration: dataclasses read from YAML in Unity ML-Agents' shape.

A config file looks like ML-Agents' (``behaviors: {Name: {trainer_type, hyperparameters,
network_settings, reward_signals, behavioral_cloning, max_steps, time_horizon, ...}}``) so that the
paper's settings (Tables 3 and 4) map one to one onto keys. Unknown keys are rejected (ML-Agents
is strict too). mimicrete's own additions are marked "extension" below:

- ``behaviors.<name>.demo_episodes``: how many demonstration episodes to use (Table 3: 60/20/10);
  the first N episodes (sorted by file name) of ``demo_path`` are loaded.
- ``behaviors.<name>.demo_drop_idle``: drop the demo steps in which the demonstrator was idle
  (every joint motion below this fraction of the env's joint step, end-effector command 0 or
  repeated); 0 keeps every step (ML-Agents). See ``train.drop_idle_steps``.
- ``reward_signals.gail.survivor_bias``: ``"none"`` (ML-Agents exactly) or ``"bootstrap"``
  (the GAIL signal bootstraps through terminal states; see ``gail.py``).
- ``env_settings`` (env_id, num_envs, seed) and ``torch_settings`` (device, num_threads).
"""

from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml


class ConfigError(ValueError):
    """A config file that does not match the schema."""


@dataclass
class Hyperparameters:
    batch_size: int = 1024
    buffer_size: int = 10240
    learning_rate: float = 3e-4
    beta: float = 5e-3
    epsilon: float = 0.2
    lambd: float = 0.95
    num_epoch: int = 3
    learning_rate_schedule: str = "linear"
    beta_schedule: str | None = None  # None: same as learning_rate_schedule (ML-Agents)
    epsilon_schedule: str | None = None
    shared_critic: bool = False


@dataclass
class NetworkSettings:
    normalize: bool = False
    hidden_units: int = 128
    num_layers: int = 2


@dataclass
class ExtrinsicSettings:
    gamma: float = 0.99
    strength: float = 1.0


@dataclass
class GailSettings:
    gamma: float = 0.99
    strength: float = 1.0
    demo_path: str = ""
    learning_rate: float = 3e-4
    use_actions: bool = False
    use_vail: bool = False
    network_settings: NetworkSettings = field(default_factory=NetworkSettings)
    survivor_bias: str = "none"  # extension: "none" | "bootstrap"


@dataclass
class RewardSignals:
    extrinsic: ExtrinsicSettings | None = None
    gail: GailSettings | None = None


@dataclass
class BehavioralCloningSettings:
    demo_path: str = ""
    strength: float = 1.0
    steps: int = 0
    batch_size: int | None = None  # None: the trainer's batch_size
    num_epoch: int | None = None  # None: the trainer's num_epoch
    samples_per_update: int = 0
    pretrain_steps: int = 0  # extension: offline BC gradient steps before the first rollout


@dataclass
class BehaviorConfig:
    trainer_type: str = "ppo"
    hyperparameters: Hyperparameters = field(default_factory=Hyperparameters)
    network_settings: NetworkSettings = field(default_factory=NetworkSettings)
    reward_signals: RewardSignals = field(default_factory=RewardSignals)
    behavioral_cloning: BehavioralCloningSettings | None = None
    max_steps: int = 500_000
    time_horizon: int = 64
    summary_freq: int = 50_000
    checkpoint_interval: int = 500_000
    keep_checkpoints: int = 5
    demo_episodes: int | None = None  # extension
    demo_drop_idle: float = 0.0  # extension: no-op filtering of the demos (0 = keep all)


@dataclass
class EnvSettings:
    env_id: str = "TileSuction-v0"
    num_envs: int = 32
    seed: int = 0


@dataclass
class TorchSettings:
    device: str = "cpu"
    num_threads: int = 1


@dataclass
class TrainerConfig:
    behavior_name: str
    behavior: BehaviorConfig
    env_settings: EnvSettings = field(default_factory=EnvSettings)
    torch_settings: TorchSettings = field(default_factory=TorchSettings)

    def to_dict(self) -> dict[str, Any]:
        """The ML-Agents-shaped dict (what ``resolved_config.yaml`` holds)."""
        return {
            "behaviors": {self.behavior_name: _asdict_clean(self.behavior)},
            "env_settings": dataclasses.asdict(self.env_settings),
            "torch_settings": dataclasses.asdict(self.torch_settings),
        }

    @property
    def demo_path(self) -> str | None:
        b = self.behavior
        if b.reward_signals.gail is not None and b.reward_signals.gail.demo_path:
            return b.reward_signals.gail.demo_path
        if b.behavioral_cloning is not None and b.behavioral_cloning.demo_path:
            return b.behavioral_cloning.demo_path
        return None


def _asdict_clean(obj: Any) -> Any:
    if dataclasses.is_dataclass(obj):
        return {
            f.name: _asdict_clean(getattr(obj, f.name))
            for f in dataclasses.fields(obj)
            if getattr(obj, f.name) is not None
        }
    return copy.deepcopy(obj)


def _build(cls: type, data: Any, where: str) -> Any:
    """Build dataclass ``cls`` from a mapping, strictly (unknown keys are an error)."""
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(f"{where}: expected a mapping, got {type(data).__name__}")
    fields = {f.name: f for f in dataclasses.fields(cls)}
    unknown = set(data) - set(fields)
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {sorted(unknown)}; allowed: {sorted(fields)}")
    kwargs: dict[str, Any] = {}
    hints = {
        "hyperparameters": Hyperparameters,
        "network_settings": NetworkSettings,
        "reward_signals": RewardSignals,
        "extrinsic": ExtrinsicSettings,
        "gail": GailSettings,
        "behavioral_cloning": BehavioralCloningSettings,
    }
    for key, value in data.items():
        sub = hints.get(key)
        keep_default = key in ("hyperparameters", "network_settings")
        if sub is not None and (value is not None or keep_default):
            kwargs[key] = _build(sub, value, f"{where}.{key}")
        else:
            kwargs[key] = _coerce(fields[key], value, f"{where}.{key}")
    return cls(**kwargs)


def _coerce(f: dataclasses.Field, value: Any, where: str) -> Any:
    t = str(f.type)
    if value is None:
        return None
    if t.startswith("int"):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or int(value) != value:
            raise ConfigError(f"{where}: expected an integer, got {value!r}")
        return int(value)
    if t.startswith("float"):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{where}: expected a number, got {value!r}")
        return float(value)
    if t.startswith("bool"):
        if not isinstance(value, bool):
            raise ConfigError(f"{where}: expected true/false, got {value!r}")
        return value
    if t.startswith("str"):
        if not isinstance(value, str):
            raise ConfigError(f"{where}: expected a string, got {value!r}")
        return value
    return value


def _validate(cfg: TrainerConfig) -> None:
    b = cfg.behavior
    h = b.hyperparameters
    if b.trainer_type != "ppo":
        raise ConfigError(f"trainer_type {b.trainer_type!r}: only 'ppo' is implemented")
    for name in ("learning_rate_schedule", "beta_schedule", "epsilon_schedule"):
        v = getattr(h, name)
        if v is not None and v not in ("linear", "constant"):
            raise ConfigError(f"hyperparameters.{name}: 'linear' or 'constant', got {v!r}")
    if h.batch_size <= 0 or h.buffer_size < h.batch_size:
        raise ConfigError("need 0 < batch_size <= buffer_size")
    if b.reward_signals.extrinsic is None and b.reward_signals.gail is None:
        raise ConfigError("reward_signals: at least one of extrinsic, gail")
    g = b.reward_signals.gail
    if g is not None:
        if g.use_vail:
            raise ConfigError("reward_signals.gail.use_vail: VAIL is not implemented")
        if g.survivor_bias not in ("none", "bootstrap"):
            raise ConfigError("reward_signals.gail.survivor_bias: 'none' or 'bootstrap'")
    if not 0.0 <= b.demo_drop_idle < 1.0:
        raise ConfigError(f"demo_drop_idle: a fraction in [0, 1), got {b.demo_drop_idle}")
    if cfg.env_settings.num_envs <= 0 or h.buffer_size % cfg.env_settings.num_envs:
        raise ConfigError("env_settings.num_envs must divide hyperparameters.buffer_size")


def from_dict(data: dict[str, Any]) -> TrainerConfig:
    if not isinstance(data, dict) or "behaviors" not in data:
        raise ConfigError("a config needs a top-level 'behaviors' mapping")
    unknown = set(data) - {"behaviors", "env_settings", "torch_settings"}
    if unknown:
        raise ConfigError(f"unknown top-level key(s) {sorted(unknown)}")
    behaviors = data["behaviors"]
    if not isinstance(behaviors, dict) or len(behaviors) != 1:
        raise ConfigError("'behaviors' must hold exactly one behavior")
    ((name, bdata),) = behaviors.items()
    cfg = TrainerConfig(
        behavior_name=str(name),
        behavior=_build(BehaviorConfig, bdata, f"behaviors.{name}"),
        env_settings=_build(EnvSettings, data.get("env_settings"), "env_settings"),
        torch_settings=_build(TorchSettings, data.get("torch_settings"), "torch_settings"),
    )
    _validate(cfg)
    return cfg


def load(path: str | Path) -> TrainerConfig:
    with open(path, encoding="utf-8") as f:
        data = yaml.safe_load(f)
    try:
        return from_dict(data)
    except ConfigError as e:
        raise ConfigError(f"{path}: {e}") from None


def with_overrides(cfg: TrainerConfig, overrides: list[str]) -> TrainerConfig:
    """Apply ``dotted.key=value`` overrides (value parsed as YAML) to the ML-Agents-shaped dict;
    ``behavior.`` is a shorthand for ``behaviors.<name>.``."""
    data = cfg.to_dict()
    for item in overrides:
        if "=" not in item:
            raise ConfigError(f"override {item!r}: expected KEY=VALUE")
        key, raw = item.split("=", 1)
        parts = key.strip().split(".")
        if parts[0] == "behavior":
            parts = ["behaviors", cfg.behavior_name, *parts[1:]]
        node = data
        for p in parts[:-1]:
            node = node.setdefault(p, {})
            if not isinstance(node, dict):
                raise ConfigError(f"override {item!r}: {p} is not a mapping")
        node[parts[-1]] = yaml.safe_load(raw)
    return from_dict(data)


def save(cfg: TrainerConfig, path: str | Path) -> None:
    with open(path, "w", encoding="utf-8") as f:
        yaml.safe_dump(cfg.to_dict(), f, sort_keys=False)
