"""The harness: what the tests, ``make bench`` and smoke runs drive mimicrete with, not part of
the pipeline a user runs. It ships in the package because ``python -m mimicrete.bench`` uses it.

- ``page_driver``: the teleoperation page in a real browser (Debian's Chromium through Playwright,
  WebXR on Meta's IWER emulator): hand logs replayed into the page, its WebSocket answered.
- ``toyenv``: a pure-numpy stand-in for the tile task with the trainer's interface (env ids
  ``Toy…``), its toy expert demos and a small config for it.

Nothing is imported here: ``import mimicrete.testing.page_driver`` imports Playwright only when a
browser is launched.
"""
