"""The engine sections are typed (mdo/settings.py), their defaults defined once, and the driver reads
a resolved section as it is: a section that is not resolved raises instead of being filled in again."""
import pytest

from bev_mdo import config as cfgmod
from bev_mdo.config import load_config
from bev_mdo.mdo.driver import build_formulation, feasibility_tolerance
from bev_mdo.mdo.evaluator import InProcessEvaluator
from bev_mdo.mdo.settings import MDASettings, OptimizerSettings
from bev_mdo.testing import REPO
from sellar import sellar_disciplines

SELLAR = REPO / "test" / "data" / "sellar.yaml"


def test_config_defaults_are_the_settings_defaults():
    assert cfgmod.MDA_DEFAULTS == MDASettings().as_dict()
    assert cfgmod.OPTIMIZER_DEFAULTS == OptimizerSettings().as_dict()


def test_a_resolved_config_reads_back_as_settings():
    cfg = load_config(SELLAR)
    assert MDASettings.of(cfg["mda"]) == MDASettings(tolerance=1e-12)
    assert OptimizerSettings.of(cfg["optimizer"]).fd_step == 1e-7
    assert feasibility_tolerance(cfg) == OptimizerSettings().feasibility_tolerance


@pytest.mark.parametrize("section,what", [({"method": "jacobi"}, "missing"), (None, "mapping")])
def test_the_driver_does_not_fill_in_an_unresolved_section(section, what):
    cfg = load_config(SELLAR)
    cfg["mda"] = section
    with pytest.raises(ValueError, match=what):
        build_formulation(cfg, InProcessEvaluator(sellar_disciplines()))


def test_settings_are_frozen():
    with pytest.raises(AttributeError):
        MDASettings().tolerance = 1.0
