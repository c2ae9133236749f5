"""Motor map: interpolation, Fig 2-9 scaling, regeneration, envelope, CSV format."""
import math
import re

import numpy as np
import pytest

from bev_mdo.models import motor_map as mm


def _tiny():
    # speeds 0, 100; torques 0, 10 Nm; values chosen to check bilinear interpolation
    return mm.MotorMap(np.array([0.0, 100.0]), np.array([0.0, 10.0]),
                       np.array([[0.5, 0.6], [0.7, 0.9]]), reference_kw=10.0, name="tiny")


def test_bilinear_by_hand():
    m = _tiny()
    # at w = 50, T = 5: mean of the four corners
    assert float(m.efficiency_at(5.0, 50.0, 10.0)) == pytest.approx((0.5 + 0.6 + 0.7 + 0.9) / 4)
    # at w = 25, T = 10: 0.6 + 0.25 (0.9 - 0.6)
    assert float(m.efficiency_at(10.0, 25.0, 10.0)) == pytest.approx(0.675)
    # outside the grid: clipped to the edge
    assert float(m.efficiency_at(50.0, 500.0, 10.0)) == pytest.approx(0.9)


def test_torque_axis_scaling_fig_2_9():
    m = _tiny()
    # a 20 kW motor at 10 Nm sits where the 10 kW unit map has 5 Nm
    assert float(m.efficiency_at(10.0, 100.0, 20.0)) == pytest.approx(0.8)
    d = mm.default_motor_map()
    np.testing.assert_allclose(d.efficiency_at([50.0, 140.0], 400.0, [40.0, 112.0]),
                               d.efficiency_at([100.0, 100.0], 400.0, 80.0))


def test_regen_same_efficiency_and_power_sign():
    m = _tiny()
    eta = float(m.efficiency_at(5.0, 50.0, 10.0))
    assert float(m.efficiency_at(-5.0, 50.0, 10.0)) == pytest.approx(eta)
    # §3.3.3: motoring P = T w / eta, regenerating P = T w * eta
    assert float(m.electrical_power_w(5.0, 50.0, 10.0)) == pytest.approx(250.0 / eta)
    assert float(m.electrical_power_w(-5.0, 50.0, 10.0)) == pytest.approx(-250.0 * eta)


def test_negative_torque_rows_used_when_present():
    m = mm.MotorMap(np.array([0.0, 100.0]), np.array([-10.0, 0.0, 10.0]),
                    np.array([[0.4, 0.5, 0.6], [0.8, 0.7, 0.9]]), reference_kw=10.0)
    assert float(m.efficiency_at(-10.0, 100.0, 10.0)) == pytest.approx(0.8)
    assert float(m.efficiency_at(10.0, 100.0, 10.0)) == pytest.approx(0.9)


def test_zero_speed_efficiency_floor():
    d = mm.default_motor_map()
    assert float(d.electrical_power_w(100.0, 0.0, 80.0)) == 0.0
    assert float(d.efficiency_at(100.0, 0.0, 80.0)) == mm.EFFICIENCY_FLOOR


def test_envelope():
    w_max = 10500 * 2 * math.pi / 60
    t = mm.max_torque_nm(np.array([0.0, 100.0, 500.0, w_max, w_max + 1]), 80.0)
    np.testing.assert_allclose(t, [280.0, 280.0, 160.0, 80e3 / w_max, 0.0])
    assert float(mm.max_torque_nm(100.0, 40.0)) == pytest.approx(140.0)
    assert float(mm.base_speed_rad_s(123.0)) == pytest.approx(1000 / 3.5)


def test_default_map_documented_figures():
    d = mm.default_motor_map()
    w = np.linspace(1, 1099, 300)[:, None]
    t = np.linspace(1, 280, 280)[None, :]
    inside = t <= mm.max_torque_nm(w, 80.0)
    # loss model by hand at the 80 kW corner (285.7 rad/s, 280 Nm)
    wc = 1000 / 3.5
    loss = 0.085 * 280 ** 2 + 2.5 * wc + 1.6e-3 * wc ** 2 + 300
    assert float(d.efficiency_at(280.0, wc, 80.0)) == pytest.approx(80e3 / (80e3 + loss), abs=2e-3)
    peak = np.max(np.where(inside, d.efficiency_at(t, w, 80.0), 0))
    assert 0.95 <= peak <= 0.96


def test_csv_roundtrip_and_shipped_default(tmp_path):
    d = mm.default_motor_map()
    shipped = mm.load_motor_map_csv(mm.DEFAULT_MAP_CSV)
    np.testing.assert_array_equal(shipped.efficiency, d.efficiency)
    np.testing.assert_array_equal(shipped.speed_rad_s, d.speed_rad_s)
    p = tmp_path / "m.csv"
    m = _tiny()
    mm.write_motor_map_csv(m, p)
    back = mm.load_motor_map_csv(p, reference_kw=10.0)
    np.testing.assert_allclose(back.efficiency, m.efficiency)
    assert back.reference_kw == 10.0


_H = "speed_rad_s,torque_nm,efficiency\n"


@pytest.mark.parametrize("text,match", [
    ("speed,torque,eta\n0,0,0.5\n", "row 1: header"),
    ("# a comment\nspeed,torque,eta\n0,0,0.5\n", "row 2: header"),
    (_H + "0,0,0.5\n0,10,0.6\n100,0,0.7\n", "full speed x torque grid"),
    (_H + "0,0,0.5\n0,10,1.5\n100,0,0.7\n100,10,0.8\n", "row 3: speed_rad_s must be >= 0"),
    (_H + "0,0,abc\n", "row 2, column efficiency: not a number: 'abc'"),
    (_H + "0,0,0.5\n0,1_0,0.6\n", "row 3, column torque_nm: not a number: '1_0'"),
    (_H + "0,0,nan\n", "row 2, column efficiency: must be finite, got nan"),
    (_H + "0,0\n", "row 2: need 3 numbers"),
    ("# a comment\n" + _H + "0,0,0.5\n0,10,x\n", "row 4, column efficiency: not a number: 'x'"),
    # the strict reader of every user CSV (cycles.read_csv_rows): a quote left open, a field over a
    # line break (the old reader took '"0.\n6"' as 0.6 and loaded the map), a quote inside a field
    (_H + '0,0,0.5\n0,10,"0.6\n100,0,0.7\n100,10,0.8\n', "row 3: a field runs over a line break into row 5"),
    (_H + '0,0,0.5\n0,10,"0.\n6"\n100,0,0.7\n100,10,0.8\n', "row 3: a field runs over a line break into row 4"),
    (_H + '0,0,0.5\n0,10,"0.6"x\n100,0,0.7\n100,10,0.8\n', "row 3: not a CSV table"),
])
def test_bad_csv(tmp_path, text, match):
    p = tmp_path / "bad.csv"
    p.write_text(text)
    with pytest.raises(ValueError, match=re.escape(match)) as err:
        mm.load_motor_map_csv(p)
    assert str(err.value).startswith(f"{p}: ") and "\n" not in str(err.value)
