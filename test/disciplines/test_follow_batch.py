"""The batch form of the cycle-follow judgement (energy.follow_batch, pareto's, one call a generation) rules out
exactly the designs the one-design form (follow_check: optimize, evaluate) does."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import qmc

from bev_mdo.api.evaluate import batch
from bev_mdo.api.overrides import Overrides, load
from bev_mdo.api.transport import Transport
from bev_mdo.disciplines.energy import follow_batch, follow_check
from bev_mdo.testing import REPO


@pytest.mark.parametrize("config", ["config/leaf_nedc.yaml", "config/topologies_artemis.yaml"])
def test_the_batch_and_the_one_design_checks_agree(config):
    cfg = load(REPO / config, Overrides(bounds={"motor_kw": (12.0, None)}))  # motors too small for the cycle too
    dvs = cfg.problem.design_variables
    x = qmc.scale(qmc.LatinHypercube(d=len(dvs), seed=2).random(60), [d.lower for d in dvs], [d.upper for d in dvs])
    res = batch(cfg, {d.name: x[:, j] for j, d in enumerate(dvs)}, Transport("inprocess"))
    values = {**res["design"], **res["outputs"]}
    params = cfg.problem.parameters
    many = follow_batch(cfg.disciplines)({**values, **{k: v for k, v in params.items() if k not in values}})
    one = follow_check(cfg.disciplines)
    each = [bool(one({**params, **{k: float(v[i]) for k, v in values.items()}})) for i in range(len(x))]
    assert 5 <= sum(each) <= 55 and list(np.asarray(many, bool)) == each
