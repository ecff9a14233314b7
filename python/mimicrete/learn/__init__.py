"""The trainer: BC + GAIL + PPO with Unity ML-Agents' semantics (torch, CPU), evaluation, plots."""
