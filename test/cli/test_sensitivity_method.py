"""``bev-mdo sensitivity --method complex`` can never run: the MDA casts every input to float64
(the discipline interface), so it used to evaluate the stencil and then blame the user's model
("complex step not supported by the model: Casting complex values to real ...") even for
disciplines written to be complex-safe. It is now one line before anything runs that says why."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bev_mdo.cli import main

SELLAR = Path(__file__).resolve().parents[2] / "examples" / "sellar" / "sellar_mdf.yaml"


def test_complex_method_is_refused_with_the_reason(capsys):
    code = main(["sensitivity", str(SELLAR), "--transport", "inprocess", "--order", "1", "--method", "complex"])
    out = capsys.readouterr()
    assert code == 2 and out.out == ""
    assert "float64" in out.err and "--method central" in out.err
    assert "not supported by the model" not in out.err


def test_auto_still_gives_central_sensitivities(capsys):
    code = main(["sensitivity", str(SELLAR), "--transport", "inprocess", "--order", "1", "--method", "auto", "--json"])
    assert code == 0 and '"method": "central"' in capsys.readouterr().out


def test_large_sensitivities_stay_separate_columns():
    """Near a zero of the output (propane's residuals at the equilibrium) normalised sensitivities
    reach 1e7 and more: the 13-wide cells ran together ('2724448.5834-30810727.5305')."""
    import io

    import numpy as np

    from bev_mdo.cli.sensitivity import print_tables
    from bev_mdo.mdo.sensitivity import sensitivities

    def fun(X):
        x, y = X[:, 0], X[:, 1]
        return {"f": 1e-6 + 3e1 * (x - 1.0) - 4e3 * (y - 2.0) ** 2 - 1e1 * (y - 2.0)}

    for order in (1, 2):
        s = sensitivities(fun, {"x": 1.0, "y": 2.0}, order=order)
        buf = io.StringIO()
        print_tables(s, ["f"], out=buf)
        lines = buf.getvalue().splitlines()
        first = next(line for line in lines if line.startswith("f "))
        assert len(first.split()) == 3, first  # the name and one number per variable
        assert abs(float(first.split()[1])) > 1e7
        if order == 2:
            second = buf.getvalue().split("Second-order")[1].splitlines()
            row = next(line for line in second if line.startswith("y "))
            assert len(row.split()) == 2, row  # the name, then the diagonal cell's value (no coupling label)
            row = next(line for line in second if line.startswith("x ") and "C" in line)
            assert len(row.split()) == 4, row  # the name, the diagonal value, the coupling's value and label


def test_a_point_that_is_not_finite_is_one_line_naming_it(capsys):
    # it was refused with a line that printed the whole point, every parameter of every discipline
    code = main(["sensitivity", str(SELLAR), "--transport", "inprocess", "--order", "1", "--at", "z1=nan"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and err == ["bev-mdo sensitivity: error: --at z1=nan: a design value must be a finite number"]


@pytest.mark.parametrize("extra", [["--order", "1"], ["--global", "morris", "--samples", "4"]])
def test_a_variable_named_twice_in_wrt_is_one_line(capsys, extra):
    """Its rows and columns were printed twice."""
    code = main(["sensitivity", str(SELLAR), "--transport", "inprocess", "--wrt", "z1,x,z1", *extra])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and err == ["bev-mdo sensitivity: error: --wrt: 'z1' named twice"]


def test_a_parameter_at_its_model_limit_gets_a_one_sided_step(capsys):
    """A van's `--wrt load_kg` at load_kg 1000, then its upper model limit, stepped to 1000.1: 'the model failed
    at 2 of the 21 points', exit 7. At a limit the step goes one-sided, as for a design variable on its bound."""
    import json

    leaf = str(Path(__file__).resolve().parents[2] / "config" / "leaf_nedc.yaml")
    argv = ["sensitivity", leaf, "--transport", "inprocess", "--order", "1", "--wrt", "load_kg", "--json"]
    assert main([*argv, "--at", "load_kg=5000"]) == 0
    at_limit = json.loads(capsys.readouterr().out)
    assert at_limit["one_sided"] == ["load_kg"]
    assert main([*argv, "--at", "load_kg=4995"]) == 0
    inside = json.loads(capsys.readouterr().out)
    for out in ("energy_wh_per_km", "range_km"):  # the one-sided slope is the two-sided one nearby
        assert at_limit["first_order"][out]["normalised"] == pytest.approx(inside["first_order"][out]["normalised"],
                                                                           rel=2e-3)


def test_an_objective_that_is_zero_at_the_point_gives_its_derivatives(capsys):
    """Ishigami at its initial point (0, 0, 0) is 0: exit 2 'output 'f' is zero at the point'. Now
    the table shows df/dx (1, 0, 0) and d2f/dx2^2 = 14 cos(2 x2) = 14 in place of the undefined S."""
    ishigami = SELLAR.parents[1] / "sensitivity" / "ishigami.yaml"
    code = main(["sensitivity", str(ishigami), "--transport", "inprocess", "--order", "2"])
    out = capsys.readouterr().out
    assert code == 0, out
    row = next(line for line in out.splitlines() if line.startswith("f ") and "df/dx_i" in line)
    assert [float(v) for v in row.split()[1:4]] == pytest.approx([1.0, 0.0, 0.0], abs=1e-6)
    x2 = next(line for line in out.splitlines() if line.startswith("x2 "))
    assert float(x2.split()[1]) == pytest.approx(14.0, rel=1e-4)


def test_a_value_the_two_steps_disagree_on_is_marked(capsys):
    # A two-motor trial: energy with a jump between the steps h and 2h printed a wrong-sign sensitivity with
    # nothing in the table to say so (only the JSON's "error"). A value whose Richardson error estimate is
    # over 1 % of it is marked "~", with a line saying why; a smooth one is not.
    import io

    from bev_mdo.cli.sensitivity import print_tables
    from bev_mdo.mdo.sensitivity import sensitivities

    def fun(X):
        x, y = X[:, 0], X[:, 1]
        return {"f": 10.0 + x + 0.5 * y + 0.01 * (x > 1.0 + 1.5e-4)}  # a jump between h and 2h of x only
    s = sensitivities(fun, {"x": 1.0, "y": 1.0})
    out = io.StringIO()
    print_tables(s, ["f"], out=out)
    row = next(line for line in out.getvalue().splitlines() if line.startswith("f "))
    x_cell, y_cell = row.split()[1:3]
    assert x_cell.endswith("~") and not y_cell.endswith("~"), row
    assert "uncertain by over 1% of the value" in out.getvalue()
    smooth = io.StringIO()
    print_tables(sensitivities(lambda X: {"f": 10.0 + X[:, 0] + 0.5 * X[:, 1]}, {"x": 1.0, "y": 1.0}), ["f"], out=smooth)
    assert "~" not in smooth.getvalue()


def test_a_second_order_entry_without_a_sure_sign_is_marked():
    # A Model 3 trial: energy's battery x battery S' printed -0.0002 where central differences give +0.0014;
    # its Richardson error (1.6e-3, in the JSON only) was larger than the value, and the table said nothing.
    # An entry whose error is over 1 % of it (and over half the last digit shown) is marked "~".
    import io

    from bev_mdo.cli.sensitivity import print_tables
    from bev_mdo.mdo.sensitivity import sensitivities

    def fun(X):
        x, y = X[:, 0], X[:, 1]
        return {"f": 10.0 + x + 0.5 * y + 0.2 * y * y + 0.01 * (x > 1.0 + 1.5e-4)}  # a jump between h and 2h of x
    s = sensitivities(fun, {"x": 1.0, "y": 1.0}, order=2)
    out = io.StringIO()
    print_tables(s, ["f"], out=out)
    second = out.getvalue().split("Second-order")[1].splitlines()
    xx = next(line for line in second if line.startswith("x "))
    yy = next(line for line in second if line.startswith("y "))
    assert xx.split()[1].endswith("~") and not yy.rstrip().endswith("~"), out.getvalue()
    assert "no sure sign" in out.getvalue()


def test_a_kink_at_the_point_itself_is_marked_though_the_two_steps_agree():
    # A Taycan-like trial: top speed = min(a cap falling with the gear, a power limit), the design on the kink.
    # Central differences at h and 2h agree on the mean of the two slopes (0.188 printed; 0.376 one side, 0 the
    # other), so the Richardson error was 0 and nothing was marked. Half the jump between the one-sided slopes
    # (the same at h and 2h) is the error now; curvature (whose jump doubles at 2h) is not taken for a kink.
    import io

    from bev_mdo.cli.sensitivity import print_tables
    from bev_mdo.mdo.sensitivity import sensitivities

    s = sensitivities(lambda X: {"v": np.minimum(2.0 * X[:, 0], 3.0 + X[:, 1] ** 2)}, {"x": 1.5, "y": 0.0})
    assert s.first["v"][0] == pytest.approx(0.5) and s.first_error["v"][0] == pytest.approx(0.5)  # slopes 1 and 0
    out = io.StringIO()
    print_tables(s, ["v"], out=out)
    row = next(line for line in out.getvalue().splitlines() if line.startswith("v "))
    assert row.split()[1].endswith("~"), row
    curved = sensitivities(lambda X: {"v": 1.0 + X[:, 0] ** 2 + X[:, 1]}, {"x": 1.0, "y": 1.0})
    assert curved.first_error["v"][0] < 1e-6


def test_a_diagonal_entry_gets_no_coupling_label():
    # A thesis reader: NC/MC/SC/VSC say how strongly two variables are coupled (Fig 5-3); the 0-100 km/h time's
    # motor_kw x motor_kw entry printed "2.2447 VSC", a variable's own curvature called a very strong coupling.
    import io

    from bev_mdo.cli.sensitivity import print_tables
    from bev_mdo.mdo.sensitivity import sensitivities

    s = sensitivities(lambda X: {"f": 1.0 + X[:, 0] ** 2 + X[:, 0] * X[:, 1]}, {"x": 1.0, "y": 1.0}, order=2)
    out = io.StringIO()
    print_tables(s, ["f"], out=out)
    second = out.getvalue().split("Second-order")[1].splitlines()
    x_row, y_row = (next(line for line in second if line.startswith(n + " ")) for n in ("x", "y"))
    assert x_row.split()[1:] == [f"{s.second['f'][0, 0]:.4f}", f"{s.second['f'][0, 1]:.4f}", "MC"], x_row
    assert y_row.split()[1:] == [f"{s.second['f'][1, 1]:.4f}"], y_row


def test_the_point_line_names_the_design_beside_a_parameter(capsys):
    """A Kona trial: with --wrt naming a parameter, the point line gave only that parameter, not the design
    (--at) the sensitivity was taken at."""
    leaf = Path(__file__).resolve().parents[2] / "config" / "leaf_nedc.yaml"
    code = main(["sensitivity", str(leaf), "--transport", "inprocess", "--order", "1", "--wrt", "drag_area_m2",
                 "--at", "motor_kw=70,gear_ratio=9,battery_kwh=22"])
    first = capsys.readouterr().out.splitlines()[0]
    assert code == 0 and first.startswith("point: motor_kw=70, gear_ratio=9, battery_kwh=22, drag_area_m2=0.6412 ")


def test_the_json_names_the_units_and_the_table_its_steps(capsys):
    """A user trial: `first_order.*.derivative` is in Wh/km per kW, yet the JSON had no units, and the table's `step`
    row no unit (a design variable's, and a model parameter's from --wrt)."""
    import json

    leaf = str(Path(__file__).resolve().parents[2] / "config" / "leaf_nedc.yaml")
    args = ["sensitivity", leaf, "--transport", "inprocess", "--order", "1", "--wrt", "motor_kw,gear_ratio,load_kg"]
    assert main([*args, "--json"]) == 0
    units = json.loads(capsys.readouterr().out)["units"]
    assert units == {"motor_kw": "kW", "gear_ratio": "1", "load_kg": "kg", "energy_wh_per_km": "Wh/km",
                     "range_km": "km", "motor_speed_max_rad_s": "rad/s", "accel_time_0_100_s": "s"}
    assert main(args) == 0
    step = next(line for line in capsys.readouterr().out.splitlines() if line.startswith("step "))
    assert step.split()[1:] == ["0.008", "kW", "0.0008", "0.0069", "kg"]  # a ratio has no unit to print


def test_a_one_sided_variable_is_said_beside_the_method(capsys):
    """The header said 'method central' of a point with gear_ratio on its upper bound, differenced one-sided
    (only the JSON's one_sided said so): one line names such variables and why."""
    argv = ["sensitivity", str(SELLAR), "--transport", "inprocess", "--order", "2"]
    assert main([*argv, "--at", "x=10"]) == 0  # on its upper bound
    lines = capsys.readouterr().out.splitlines()
    assert "method central" in lines[0]
    assert lines[1].startswith("one-sided differences for x: on or within two steps of a bound")
    assert main([*argv, "--at", "x=5"]) == 0
    assert "one-sided" not in capsys.readouterr().out


def test_the_json_labels_agree_with_the_legend_on_the_diagonal(capsys):
    """The legend says a diagonal entry (one variable's own curvature) has no coupling label; the JSON gave
    each one (NC, MC ...). Now null there, a label on every pair of variables."""
    import json

    code = main(["sensitivity", str(SELLAR), "--transport", "inprocess", "--order", "2", "--json"])
    rep = json.loads(capsys.readouterr().out)
    assert code == 0
    for out, sec in rep["second_order"].items():
        for i, row in enumerate(sec["labels"]):
            for j, lab in enumerate(row):
                assert (lab is None) if i == j else lab in ("NC", "MC", "SC", "VSC"), (out, i, j, lab)


@pytest.mark.parametrize("value", ["0", "0.5", "nan"])
def test_a_rel_step_out_of_range_names_the_flag_as_typed(capsys, value):
    """It was 'rel_step must be in (0, 0.5), got 0.0': the API's name, not the flag's."""
    code = main(["sensitivity", str(SELLAR), "--transport", "inprocess", "--order", "1", f"--rel-step={value}"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and err == [f"bev-mdo sensitivity: error: --rel-step {float(value):g}: must be in (0, 0.5)"]


def test_the_raw_derivatives_of_an_output_zero_but_for_rounding_carry_their_marks():
    """Its rows show df/dx and d2f/dx2 in place of S and S'; those were never marked, so a d2f of -1.568e15 from
    steps that disagree (sellar_vector's con[0] at its optimum) stood unflagged where S' had read -123~."""
    import io

    from bev_mdo.cli.sensitivity import ROUGH, print_tables
    from bev_mdo.mdo.sensitivity import sensitivities

    s = sensitivities(lambda X: {"zero": X[:, 0] * X[:, 1] - 0.3 + 1e3 * np.abs(X[:, 0] - 3.0)}, {"x": 3.0, "y": 0.1},
                      order=2)
    assert s.undefined == ["zero"] and s.hessian_error["zero"][0, 0] > ROUGH * abs(s.hessian["zero"][0, 0])
    out = io.StringIO()
    print_tables(s, ["zero"], out=out)
    row = next(line for line in out.getvalue().splitlines()[::-1] if line.startswith("x "))
    assert row.split()[1].endswith("~"), out.getvalue()  # its own curvature through the kink
