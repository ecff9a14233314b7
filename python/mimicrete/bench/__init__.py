"""Benchmarks printed by ``make bench``. One module per area, each with ``run() -> None`` that
prints its figures (ratios against a peer measured in the same run where a peer exists)."""
