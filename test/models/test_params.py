import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from bev_mdo.models.common import check_array, validate_design
from bev_mdo.models.params import (VEHICLE_CHOICES, VEHICLE_SPECS, validate_cycle,
                                   validate_vehicle, vehicle_choice)


def test_defaults_filled_and_in_range():
    v = validate_vehicle({"drag_area_m2": 0.7})
    assert v["drag_area_m2"] == 0.7
    assert v["rolling_resistance"] == VEHICLE_SPECS["rolling_resistance"].default
    for k, s in VEHICLE_SPECS.items():
        assert s.lower <= s.default <= s.upper, k


def test_unknown_name_lists_known():
    with pytest.raises(ValueError, match="vehicle.drag_aera.*: unknown key; did you mean 'drag_area_m2'"):
        validate_vehicle({"drag_aera": 0.6})


@pytest.mark.parametrize("name,value", [("drag_area_m2", -1), ("rolling_resistance", float("nan")),
                                        ("gear_efficiency", 1.2), ("wheel_radius_m", "big")])
def test_bad_value_names_parameter_and_range(name, value):
    with pytest.raises(ValueError, match=rf"^{name} must be .*\[") as e:
        validate_vehicle({name: value})
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("name", ["glider_kg", "battery_usable_fraction"])
def test_a_yaml_bool_is_not_a_number(name):
    # float(True) is 1: glider_kg: true was read as 1 kg, battery_usable_fraction: true as 1.0 (accepted)
    with pytest.raises(ValueError, match=rf"^{name} must be a number in \[.*\].*, got true \(a bool\)$"):
        validate_vehicle({name: True})


def test_mass_model_choice():
    with pytest.raises(ValueError, match="mass_model"):
        validate_vehicle({"mass_model": "heavy"})
    assert "mass_model" not in validate_vehicle({"mass_model": "compounding"})


def test_topology_choice():
    from bev_mdo.models.topology import TOPOLOGIES

    assert VEHICLE_CHOICES["topology"] == TOPOLOGIES
    for name in TOPOLOGIES:
        assert "topology" not in validate_vehicle({"topology": name})  # checked, not a number
        assert vehicle_choice({"topology": name.lower()}, "topology") == name  # any case, like get_topology
    assert vehicle_choice({}, "topology") == "SM-SA"
    for bad in ("IWM", "SM_SA", 3, None):
        with pytest.raises(ValueError) as e:
            validate_vehicle({"topology": bad})
        assert str(e.value) == f"topology must be one of SM-SA, DM-DA, IWM-SA, IWM-DA, got {bad!r}"


def test_cycle_section():
    # default interpolation is linear (the NEDC is piecewise linear by regulation)
    assert validate_cycle({"name": "nedc"}) == {"name": "nedc", "dt_s": 1.0, "interpolation": "linear", "smoothing": None}
    with pytest.raises(ValueError, match="dt_s"):
        validate_cycle({"dt_s": 0})
    with pytest.raises(ValueError, match="interpolation"):
        validate_cycle({"interpolation": "cubic"})
    with pytest.raises(ValueError, match="cycle.[a-z_]+: unknown key"):
        validate_cycle({"speed": 3})


def test_validate_design():
    assert validate_design("motor_kw", [40, 120], 40, 120).tolist() == [40.0, 120.0]
    with pytest.raises(ValueError, match=r"motor_kw must be in \[40, 120\]"):
        validate_design("motor_kw", [39.9], 40, 120)


def _outcome(values):
    try:
        return check_array("motor_kw", values, 1.0, 1000.0, "kW")
    except ValueError as exc:
        return str(exc)


@given(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([(), (1,), (1, 1)]))
def test_check_array_one_point_agrees_with_the_batch_path(x, shape):
    """The one-point shortcut accepts and rejects exactly what the vector check does, with its message."""
    one = _outcome(np.full(shape, x))
    batch = _outcome(np.array([x, x]))
    if isinstance(batch, str):
        assert one == batch
    else:
        assert not isinstance(one, str) and one.shape == shape and (one == x).all()
