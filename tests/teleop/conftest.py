"""The browser the page tests drive: Debian's Chromium through Playwright (one per module)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

from mimicrete.teleop.server import STATIC
from mimicrete.testing import page_driver as br


@pytest.fixture(scope="module")
def chromium() -> Iterator[Any]:
    if not (STATIC / "index.html").exists():
        pytest.fail(f"{STATIC} has no built page: run `make web` (npm ci && npm run build in web/)")
    with br.launch() as b:
        yield b
