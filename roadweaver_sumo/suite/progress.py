"""Progress of long suite work on stderr: one line per finished scenario with n/N, elapsed
time and an ETA, so it reads the same in a terminal, a CI log or a file."""

from __future__ import annotations

import sys
import time
from typing import TextIO

BAR_WIDTH = 20


class Progress:
    """Counts finished items of ``total``; ``enabled=False`` (``--quiet``, ``--json``) prints
    nothing. The ETA assumes the remaining items take as long as the finished ones on average."""

    def __init__(self, total: int, enabled: bool = True, stream: TextIO | None = None) -> None:
        self.total, self.enabled = total, enabled
        self.stream = stream if stream is not None else sys.stderr
        self.done_count = 0
        self.start = time.monotonic()

    def say(self, message: str) -> None:
        if self.enabled:
            print(message, file=self.stream, flush=True)

    def done(self, name: str, status: str) -> None:
        self.done_count += 1
        if not self.enabled:
            return
        n, total = self.done_count, self.total
        elapsed = time.monotonic() - self.start
        eta = elapsed / n * (total - n)
        filled = round(BAR_WIDTH * n / max(total, 1))
        bar = "#" * filled + "." * (BAR_WIDTH - filled)
        width = len(str(total))
        self.say(f"[{bar}] {n:>{width}}/{total} {_clock(elapsed)} elapsed, ETA {_clock(eta)}"
                 f"  {status:<7} {name}")  # fmt: skip


def _clock(seconds: float) -> str:
    seconds = round(seconds)
    hours, rest = divmod(seconds, 3600)
    return f"{hours}:{rest // 60:02d}:{rest % 60:02d}" if hours else f"{rest // 60}:{rest % 60:02d}"
