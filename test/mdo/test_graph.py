import pytest

from bev_mdo.mdo.graph import CouplingGraph

BEV = [
    ("vehicle_mass", ("motor_kw", "battery_kwh"), ("vehicle_mass_kg",)),
    ("energy", ("vehicle_mass_kg", "gear_ratio"), ("energy_wh_per_km",)),
    ("range", ("energy_wh_per_km", "battery_kwh"), ("range_km",)),
    ("acceleration", ("vehicle_mass_kg", "motor_kw", "gear_ratio"), ("accel_time_0_100_s",)),
    ("motor_speed", ("gear_ratio",), ("motor_speed_max_rad_s",)),
    ("cost", ("motor_kw", "battery_kwh"), ("powertrain_cost_usd",)),
]


def test_feed_forward_waves_follow_fig_7_17():
    g = CouplingGraph(BEV)
    assert g.waves == [[("vehicle_mass",), ("motor_speed",), ("cost",)],
                       [("energy",), ("acceleration",)], [("range",)]]
    assert g.cycles == []
    assert g.external_inputs == ["battery_kwh", "gear_ratio", "motor_kw"]
    assert g.couplings == ["energy_wh_per_km", "vehicle_mass_kg"]


def test_battery_sizing_makes_one_loop_and_downstream_waits():
    spec = [(n, i, o) for n, i, o in BEV] + [("battery_sizing", ("energy_wh_per_km",), ("battery_kwh",))]
    g = CouplingGraph(spec)
    assert g.cycles == [("vehicle_mass", "energy", "battery_sizing")]
    order = [c for w in g.waves for c in w]
    assert order.index(("vehicle_mass", "energy", "battery_sizing")) < order.index(("range",))
    assert order.index(("vehicle_mass", "energy", "battery_sizing")) < order.index(("cost",))
    assert g.torn_inputs(("vehicle_mass", "energy", "battery_sizing")) == ["battery_kwh"]


def test_self_loop_is_a_cycle():
    g = CouplingGraph([("a", ("x", "y"), ("y",))])
    assert g.cycles == [("a",)]


def test_output_produced_twice_is_named():
    with pytest.raises(ValueError, match="'y' is produced by both 'a' and 'b'"):
        CouplingGraph([("a", ("x",), ("y",)), ("b", ("x",), ("y",))])


def test_unproduced_input_is_named():
    g = CouplingGraph([("a", ("x", "w"), ("y",))])
    g.check_inputs({"x", "w"})
    with pytest.raises(ValueError, match=r"'a' needs \['w'\]"):
        g.check_inputs({"x"})


def test_an_unproduced_input_says_what_it_nearly_is():
    """A user trial: a consumer that read a 2-element vector as a scalar was told 'needs ['P_loss'], which no
    discipline produces' (its producer does, as P_loss[0], P_loss[1]); a misspelt input got no hint."""
    g = CouplingGraph([("elec", ("h",), ("P_loss[0]", "P_loss[1]")), ("econ", ("P_loss",), ("cost",))])
    with pytest.raises(ValueError, match=r"\('P_loss' is a vector of 2 elements \(discipline 'elec'\): add shapes = "
                                         r"\{'P_loss': 2\} to 'econ'\)"):
        g.check_inputs({"h"})
    g = CouplingGraph([("elec", ("h",), ("P_loss[0]", "P_loss[1]")), ("econ", ("P_los[0]", "P_los[1]"), ("cost",))])
    with pytest.raises(ValueError, match=r"needs \['P_los\[0\]', 'P_los\[1\]'\], .* \(did you mean 'P_loss'\?\)$"):
        g.check_inputs({"h"})


def test_inputs_no_one_gives_are_named_for_every_discipline_without_a_misleading_hint():
    """A two-axle topology without motor_rear_kw: one discipline's error at a time, with "did you mean
    'motor_kw'?", another input rather than a misspelling of it."""
    g = CouplingGraph([("mass", ("motor_kw", "motor_rear_kw"), ("m",)), ("acc", ("m", "motor_rear_kw", "g_rear"), ("t",))])
    with pytest.raises(ValueError) as e:
        g.check_inputs({"motor_kw"})
    assert str(e.value) == ("discipline 'mass' needs ['motor_rear_kw'], which no discipline produces and which are not "
                            "design variables or parameters; also 'acc' needs ['motor_rear_kw', 'g_rear']")
    with pytest.raises(ValueError, match=r"\(did you mean 'motor_kws'\?\)"):  # a given name no one reads: misspelt
        g.check_inputs({"motor_kws", "motor_rear_kw", "g_rear"})
    # the review: a misspelt coupling another discipline reads ('y_1' for y1) kept its hint
    g = CouplingGraph([("d1", ("x",), ("y1",)), ("d2", ("y1",), ("y2",)), ("typo", ("y_1", "y2"), ("t",))])
    with pytest.raises(ValueError, match=r"'typo' needs \['y_1'\], .* \(did you mean 'y1'\?\)$"):
        g.check_inputs({"x"})


def test_duplicate_discipline_names_rejected():
    with pytest.raises(ValueError, match="used twice"):
        CouplingGraph([("a", ("x",), ("y",)), ("a", ("x",), ("z",))])
