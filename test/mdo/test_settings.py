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


# -- RunSettings: built once in config.py, passed down -------------------------------------
def test_run_settings_hold_what_the_engine_needs_and_are_frozen():
    import dataclasses

    from bev_mdo.mdo.settings import RunSettings

    cfg = load_config(SELLAR)
    run = cfgmod.run_settings(cfg)
    assert isinstance(run, RunSettings)
    assert run.disciplines == tuple(cfgmod.discipline_names(cfg)) and set(run.partials) == set(run.disciplines)
    assert run.mda == MDASettings.of(cfg["mda"]) and run.optimizer == OptimizerSettings.of(cfg["optimizer"])
    assert run.formulation == cfg["formulation"] and run.problem == cfg["problem"]
    with pytest.raises(dataclasses.FrozenInstanceError):
        run.formulation = "idf"
    leaf = cfgmod.run_settings(load_config(REPO / "config" / "leaf_nedc.yaml"))  # the default BEV disciplines
    from bev_mdo.mdo.vectors import has_partials

    leaf_cfg = load_config(REPO / "config" / "leaf_nedc.yaml")
    assert leaf.partials == {d.name: has_partials(d) for d in cfgmod.resolve_disciplines(leaf_cfg)}
    assert "energy" in leaf.disciplines and not leaf.partials["energy"]


def test_the_driver_gives_the_same_formulation_from_run_settings_or_a_config():
    from bev_mdo.config import resolve_disciplines

    cfg = load_config(REPO / "config" / "leaf_nedc.yaml")
    ev = InProcessEvaluator(resolve_disciplines(cfg))
    a, b = build_formulation(cfg, ev), build_formulation(cfgmod.run_settings(cfg), ev)
    assert list(a.mda.specs) == list(b.mda.specs) == list(cfgmod.discipline_names(cfg))
    assert (a.name, a.derivatives) == (b.name, b.derivatives)


def test_a_config_over_a_transport_that_does_not_declare_partials_asks_for_run_settings():
    """Over ROS the declarations carry no partials: the driver does not guess from a config."""
    from dataclasses import replace

    cfg = load_config(SELLAR)
    ev = InProcessEvaluator(sellar_disciplines())
    ev.specs = {n: replace(s, partials=None) for n, s in ev.specs.items()}
    with pytest.raises(ValueError, match="run_settings"):
        build_formulation(cfg, ev)
    run = cfgmod.run_settings(cfg)
    form = build_formulation(run, ev)
    want = "analytic" if all(run.partials.values()) else "fd"
    assert form.derivatives == want
