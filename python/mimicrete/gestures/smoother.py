"""Per-frame gestures → a stable command stream (hysteresis)."""

from __future__ import annotations

from collections import deque


class GestureSmoother:
    """Hysteresis over a stream of per-frame gestures.

    The output only switches to a new gesture once it has won at least ``k`` of the last ``n``
    classified frames; until then the previous output holds. Untracked frames (``None``) are
    skipped (they neither vote nor clear the history). With ``k > n // 2`` a single misread frame,
    or any ``n - k`` misread frames in a window, can never change the output.
    """

    def __init__(self, n: int = 7, k: int = 5, initial: str | None = None) -> None:
        if not 0 < k <= n:
            raise ValueError(f"need 0 < k <= n, got k={k}, n={n}")
        self.n, self.k = n, k
        self.initial = initial
        self.state: str | None = initial
        self._window: deque[str] = deque(maxlen=n)

    def reset(self) -> None:
        """Forget the history and go back to the initial output."""
        self.state = self.initial
        self._window.clear()

    def update(self, label: str | None) -> str | None:
        """Feed one frame's classification (``None`` = no usable hand); returns the output."""
        if label is None:
            return self.state
        self._window.append(label)
        if label != self.state:
            if sum(1 for x in self._window if x == label) >= self.k:
                self.state = label
        return self.state
