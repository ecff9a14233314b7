"""Config overrides the trainer tests share."""

#: A small trainer run on the real env: a 1024-step buffer in 256-step batches, a 2 × 32 net and
#: 20 BC warm-start steps.
SMALL_RUN = [
    "behavior.hyperparameters.buffer_size=1024",
    "behavior.hyperparameters.batch_size=256",
    "behavior.network_settings.hidden_units=32",
    "behavior.network_settings.num_layers=2",
    "behavior.behavioral_cloning.pretrain_steps=20",
]
