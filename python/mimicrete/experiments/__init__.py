"""The paper's experiments: Table 3's nine groups x seeds as a Ray Tune sweep, and the results
report generated from the run directories.

``sweep.py`` (the Tune sweep, resumable; ``python -m mimicrete.experiments``), ``trials.py`` (one
trial = one training run + evaluation, its ``trial.json``), ``sweep_runs.py`` (the sweep's run
dirs read back), ``stats.py`` (the report's numbers), ``paper.py`` (what the paper reports),
``figures.py`` and ``report.py`` (``docs/RESULTS.md``; ``python -m mimicrete.experiments.report``).
"""
