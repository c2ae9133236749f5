"""Test discipline for worker pools: each design costs a fixed wait (time.sleep, no CPU).

So a 2-core host can show how a pool scales: N instances that each sleep for their share
take 1/N of the time, whatever the cores. The value is a deterministic function of each row
alone, so a batch split among instances must give bitwise the same answer as one instance.

With the environment variable BEV_POOL_STALL_S set, the process sleeps that long on its first
call with more than one design (an instance that stalls mid-batch).
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass

import numpy as np


class WaitPerDesign:
    name = "wait"
    inputs = ("motor_kw", "gear_ratio")
    outputs = ("wait_value",)
    units = {"motor_kw": "kW", "gear_ratio": "1", "wait_value": "1"}
    parameters = {}

    def __init__(self, wait_s_per_design: float = 0.002, overhead_s: float = 0.0):
        self.wait_s = float(wait_s_per_design)
        self.overhead_s = float(overhead_s)
        self._stall_s = float(os.environ.get("BEV_POOL_STALL_S", "0") or 0)

    @dataclass(frozen=True)
    class Options:  # the keys its config entry may give (any other is refused at load)
        wait_s_per_design: float = 0.002
        overhead_s: float = 0.0

    @classmethod
    def from_config(cls, config, options):
        return cls(wait_s_per_design=options.wait_s_per_design, overhead_s=options.overhead_s)

    def compute(self, inputs):
        x, g = np.asarray(inputs["motor_kw"], float), np.asarray(inputs["gear_ratio"], float)
        n = x.shape[0]
        if self._stall_s and n > 1:
            stall, self._stall_s = self._stall_s, 0.0
            time.sleep(stall)
        time.sleep(self.overhead_s + self.wait_s * n)
        return {"wait_value": np.sin(x) * np.sqrt(g) + x / (1.0 + g * g)}
