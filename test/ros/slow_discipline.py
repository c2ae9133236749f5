"""Test disciplines for fault handling: built-in range that stalls on its first call."""
from __future__ import annotations

import time
from dataclasses import dataclass

from bev_mdo.disciplines import Range


class SlowFirstRange(Range):
    """The built-in range discipline, but the first compute() of the process sleeps `delay_s`."""

    _calls = 0

    @dataclass(frozen=True)
    class Options:
        delay_s: float = 1.0

    @classmethod
    def from_config(cls, config, options):
        obj = super().from_config(config, Range.Options())
        obj.delay_s = float(options.delay_s)
        return obj

    def compute(self, inputs):
        type(self)._calls += 1
        if type(self)._calls == 1:
            time.sleep(self.delay_s)  # deliberate: simulates a node that stalls beyond the timeout
        return super().compute(inputs)
