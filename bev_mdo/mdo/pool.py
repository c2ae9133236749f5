"""Worker pools: several live instances of one discipline share each batch.

No rclpy import here: the split, the throughput estimate and the per-instance counters are
plain Python, used by the orchestrator (orchestrator.py) and tested without ROS. A batch is cut into
contiguous row ranges in proportion to each instance's measured throughput (points per second, an
exponentially weighted mean); the answers are joined in row order. The split, suspects, the modes
(``ros.pool``: ``share`` or ``redundant``) and ``ros.pool_min_rows``: docs/scaling.md, "Worker pools".
"""
from __future__ import annotations

from dataclasses import dataclass, field

POOL_MODES = ("share", "redundant")
ALPHA = 0.5  # weight of the newest throughput sample


@dataclass
class InstanceStats:
    """What one instance did in a run (shown in the run summary)."""

    shares: int = 0             # shares answered and accepted
    points: int = 0             # designs evaluated in those shares
    busy_s: float = 0.0         # wall time from sending a share to accepting its answer, summed
    failures: int = 0           # shares it held when it timed out or left the graph
    reassigned_points: int = 0  # designs taken from it and given to others
    throughput: float = 0.0     # points per second (weighted mean of the latest shares)

    def to_dict(self) -> dict:
        return {"shares": self.shares, "points": self.points, "busy_s": round(self.busy_s, 6),
                "failures": self.failures, "reassigned_points": self.reassigned_points,
                "throughput_points_per_s": round(self.throughput, 3)}


@dataclass
class Pool:
    """The instances of one discipline, their throughput and their record."""

    discipline: str
    stats: dict[str, InstanceStats] = field(default_factory=dict)
    suspect: set[str] = field(default_factory=set)

    def stat(self, instance: str) -> InstanceStats:
        return self.stats.setdefault(instance, InstanceStats())

    def revive(self, instance: str) -> None:
        """A (re)declared instance may get work again."""
        self.suspect.discard(instance)
        self.stat(instance)

    def record(self, instance: str, n: int, elapsed_s: float) -> None:
        """An accepted share of `n` points answered `elapsed_s` after it was sent."""
        s = self.stat(instance)
        s.shares += 1
        s.points += n
        s.busy_s += elapsed_s
        if n > 0 and elapsed_s > 0:
            rate = n / elapsed_s
            s.throughput = rate if s.throughput <= 0 else ALPHA * rate + (1 - ALPHA) * s.throughput

    def fail(self, instance: str, n: int) -> None:
        """`instance` held a share of `n` points and timed out or left: no more work for it."""
        s = self.stat(instance)
        s.failures += 1
        s.reassigned_points += n
        self.suspect.add(instance)

    def weights(self, instances: list[str]) -> list[float]:
        measured = [self.stat(i).throughput for i in instances if self.stat(i).throughput > 0]
        default = sum(measured) / len(measured) if measured else 1.0
        return [self.stat(i).throughput if self.stat(i).throughput > 0 else default for i in instances]

    def split(self, n: int, instances: list[str], min_rows: int = 1) -> list[tuple[str, int, int]]:
        """[(instance, start row, stop row)] covering 0..n in order, in proportion to throughput;
        with ``min_rows`` > 1 no share is smaller than that (fewer instances get work instead,
        the fastest first), except a batch smaller than ``min_rows``, which is one share."""
        weights = self.weights(instances)
        if min_rows > 1 and n >= 1:
            keep = max(1, min(len(instances), n // min_rows))
            best = sorted(sorted(range(len(instances)), key=lambda j: -weights[j])[:keep])
            instances, weights = [instances[j] for j in best], [weights[j] for j in best]
            sizes = [b - a for _, a, b in split_rows(n, instances, weights)]
            for j in range(len(sizes)):  # n >= keep * min_rows: the largest can always give
                while 0 < sizes[j] < min_rows and n >= min_rows:
                    big = max(range(len(sizes)), key=lambda i: sizes[i])
                    sizes[big] -= 1
                    sizes[j] += 1
            return _ranges(instances, sizes)
        return split_rows(n, instances, weights)


def split_rows(n: int, instances: list[str], weights: list[float]) -> list[tuple[str, int, int]]:
    """Cut rows 0..n into contiguous ranges in proportion to `weights` (largest remainder), at
    least one row each while n >= len(instances); instances given no row are left out."""
    k = len(instances)
    if k == 0:
        return []
    if n <= 0:
        return [(instances[0], 0, 0)]
    total = float(sum(weights)) or 1.0
    exact = [n * w / total for w in weights]
    sizes = [int(e) for e in exact]
    left = n - sum(sizes)
    for j in sorted(range(k), key=lambda j: exact[j] - int(exact[j]), reverse=True)[:left]:
        sizes[j] += 1
    if n >= k:  # at least one row each: taken from the largest share
        for j in range(k):
            if sizes[j] == 0:
                sizes[max(range(k), key=lambda i: sizes[i])] -= 1
                sizes[j] = 1
    return _ranges(instances, sizes)


def _ranges(instances: list[str], sizes: list[int]) -> list[tuple[str, int, int]]:
    """[(instance, start row, stop row)] of consecutive ranges of ``sizes`` rows; empty ones left out."""
    out, start = [], 0
    for inst, size in zip(instances, sizes):
        if size > 0:
            out.append((inst, start, start + size))
            start += size
    return out


def min_rows_of(setting, discipline: str) -> int:
    """The ``ros.pool_min_rows`` of one discipline (1: cut into as many shares as instances)."""
    return setting.get(discipline, 1) if isinstance(setting, dict) else int(setting)


def validate_mode(mode) -> str:
    if mode not in POOL_MODES:
        raise ValueError(f"ros.pool must be one of {list(POOL_MODES)}, got {mode!r}")
    return mode
