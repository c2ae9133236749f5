"""The motor_speed discipline (eq 7-29) with a two-speed gearbox: the thesis' single-speed formula,
first gear x the cycle's top speed, held a van's motor at 468 rad/s where its second gear turns it at 234
(the optimum then sat on a limit the motor never meets)."""
from pathlib import Path

import numpy as np
import pytest
import yaml

from bev_mdo.config import RunConfig
from bev_mdo.mdo.discipline import run_discipline

LEAF = Path(__file__).resolve().parents[2] / "config" / "leaf_nedc.yaml"
KMH = 1 / 3.6


def _motor_speed(**vehicle):
    raw = yaml.safe_load(LEAF.read_text())
    raw["vehicle"].update(vehicle)
    raw["problem"]["design_variables"]["gear_ratio"]["lower"] = 4.7  # a two-speed box's second gear (4.7) is no
    # shorter than the first, checked on load; the discipline itself is run below at any ratio, 3 and 4 too
    return next(d for d in RunConfig.load(raw).disciplines if d.name == "motor_speed")


@pytest.mark.parametrize("ratios", [[8.0, 12.0], [3.0, 4.0]])
def test_a_two_speed_gearbox_turns_the_motor_in_its_second_gear_above_the_shift_speed(ratios):
    ig, r, v_max = np.array(ratios), 0.316, 120 * KMH  # NEDC's top speed
    one = run_discipline(_motor_speed(), {"gear_ratio": ig}).outputs["motor_speed_max_rad_s"]
    assert one == pytest.approx(ig * v_max / r, rel=1e-12)
    ms = _motor_speed(gear_count=2, gear_ratio_2=4.7, shift_speed_m_s=68.1 * KMH)
    two = run_discipline(ms, {"gear_ratio": ig}).outputs["motor_speed_max_rad_s"]
    # first gear up to 68.1 km/h, the second (4.7) above it, up to 120 km/h
    assert two == pytest.approx(np.maximum(ig * 68.1 * KMH, 4.7 * v_max) / r, rel=1e-12)
    # its partial in gear_ratio against a central difference (0 where the second gear sets the speed)
    partial = ms.compute_partials({"gear_ratio": ig})[("motor_speed_max_rad_s", "gear_ratio")]
    h = 1e-6
    fd = (run_discipline(ms, {"gear_ratio": ig + h}).outputs["motor_speed_max_rad_s"]
          - run_discipline(ms, {"gear_ratio": ig - h}).outputs["motor_speed_max_rad_s"]) / (2 * h)
    assert partial == pytest.approx(fd, rel=1e-6, abs=1e-9)
    # choosing the gear per step may use the first at any speed: the single-speed bound stays
    per_step = _motor_speed(gear_count=2, gear_ratio_2=4.7, shift_strategy=1)
    assert run_discipline(per_step, {"gear_ratio": ig}).outputs["motor_speed_max_rad_s"] == pytest.approx(one)


def test_the_gearbox_follows_a_per_point_override():
    ms = _motor_speed(gear_ratio_2=4.7, shift_speed_m_s=68.1 * KMH)
    out = run_discipline(ms, {"gear_ratio": np.array([8.0, 8.0]), "gear_count": np.array([1.0, 2.0])})
    assert out.outputs["motor_speed_max_rad_s"] == pytest.approx([8 * 120 * KMH / 0.316, 4.7 * 120 * KMH / 0.316])
