"""models/follow.py in blocks of designs: a sweep of 100,000 designs on a 1,180-step cycle held about
5 GB at once (every (steps x designs) array); in blocks the answer is the same and each block is small."""
import numpy as np

from bev_mdo.models import follow
from bev_mdo.models.cycles import load_cycle


def test_blocks_give_the_same_answer_and_stay_small(monkeypatch):
    cyc = load_cycle("nedc")
    rng = np.random.default_rng(3)
    n = 2500
    designs = (rng.uniform(1300, 2000, n), rng.uniform(4, 12, n), rng.uniform(30, 200, n))
    params = {"tyre_grip_coefficient": rng.uniform(0.6, 1.0, n)}  # a per-design parameter rides along
    whole = follow.steps_not_followed(cyc.time_s, cyc.speed_m_s, params, *designs)
    cells = []
    inner = follow._block
    monkeypatch.setattr(follow, "_CELLS", 50_000)
    monkeypatch.setattr(follow, "_block", lambda t, v, p, m, *a: (cells.append((len(v) - 1) * len(m)), inner(t, v, p, m, *a))[1])
    blocked = follow.steps_not_followed(cyc.time_s, cyc.speed_m_s, params, *designs)
    assert len(cells) > 50 and max(cells) <= 50_000
    assert 0 < whole[0].sum() and np.array_equal(whole[0], blocked[0]) and np.array_equal(whole[1], blocked[1])
