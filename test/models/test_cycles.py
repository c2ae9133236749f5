import re

import numpy as np
import pytest

from bev_mdo.models import cycles
from bev_mdo.models.cycles import DriveCycle, concatenate, load_cycle, nedc, read_cycle_csv, resample


def test_nedc_regulation_figures():
    c = nedc()
    assert c.duration_s == 1180.0
    # 4 ECE-15 of 3652.5 km/h*s each plus EUDC 25037.5 km/h*s, summed by hand from R83 tables
    assert c.distance_m == pytest.approx((4 * 3652.5 + 25037.5) / 3.6, rel=1e-12)
    assert c.distance_m / 1000 == pytest.approx(11.013, abs=5e-4)
    assert c.mean_speed_kmh == pytest.approx(33.6, abs=0.05)
    assert c.max_speed_kmh == pytest.approx(120.0)


def test_ece15_distance_close_to_regulation_1013m():
    u = cycles.ece15()
    assert u.duration_s == 195.0
    assert u.distance_m == pytest.approx(1013.0, rel=2e-3)  # R83 nominal 1.013 km
    # the four urban repeats of the NEDC each cover the same distance
    c = nedc()
    for k in range(4):
        m = (c.time_s >= 195 * k) & (c.time_s <= 195 * (k + 1))
        assert np.trapezoid(c.speed_m_s[m], c.time_s[m]) == pytest.approx(u.distance_m)


def test_trapezoid_distance_three_samples():
    c = DriveCycle("t", np.array([0.0, 2.0, 3.0]), np.array([0.0, 4.0, 4.0]))
    assert c.distance_m == pytest.approx(0.5 * 2 * 4 + 4.0)
    assert c.mean_speed_kmh == pytest.approx((8.0 / 3.0) * 3.6)


def test_artemis_combined_is_2u_2r_1m130():
    u, r, m = (load_cycle(n) for n in ("artemis_urban", "artemis_rural_road", "artemis_motorway_130"))
    c = load_cycle("artemis_combined")
    assert c.distance_m == pytest.approx(2 * u.distance_m + 2 * r.distance_m + m.distance_m)
    assert c.duration_s == pytest.approx(2 * u.duration_s + 2 * r.duration_s + m.duration_s)
    assert np.all(np.diff(c.time_s) > 0)


def test_concatenate_nonzero_joint_adds_a_step():
    a = DriveCycle("a", np.array([0.0, 1.0]), np.array([0.0, 1.0]))
    b = DriveCycle("b", np.array([0.0, 1.0]), np.array([2.0, 0.0]))
    c = concatenate([a, b], "ab")
    assert list(c.time_s) == [0.0, 1.0, 2.0, 3.0]
    assert list(c.speed_m_s) == [0.0, 1.0, 2.0, 0.0]


@pytest.mark.parametrize("body,row", [
    ("time_s,speed_kmh\n0,0\n1,5\n1,6\n", 4),
    ("time_s,speed_kmh\n0,0\n1,-5\n", 3),
    ("time_s,speed_kmh\n0,0\n1,nan\n", 3),
    ("time_s,speed_kmh\n0,0\n1,abc\n", 3),
    ("time,speed\n0,0\n", 1),
    ("time_s,speed_kmh\n0,0\n\n1,600\n", 4),          # blank rows keep the file's row numbers
    ("time_s,speed_kmh\n0,0\n5000,0\n", 3),            # gap
    ("time_s,speed_kmh\n0,0\n1,100\n", 3),             # acceleration
    ("time_s,speed_kmh\n0,0\ninf,1\n", 3),
    ("time_s,speed_kmh\n0,0\n0.5,600\n1,1,2\n", 3),   # the first bad row, before a later row's column error
    ("time_s,speed_kmh\n0,0\n1,1,2\n2,600\n", 3),
    ("time_s,speed_kmh\n0,0\n1,x\n0,0\n", 3),
    ("time_s,speed_kmh\n0,0\n", 0),                     # one data row: "needs at least 2 data rows"
])
def test_csv_errors_name_file_and_row(tmp_path, body, row):
    p = tmp_path / "bad_cycle.csv"
    p.write_text(body)
    with pytest.raises(ValueError) as e:
        read_cycle_csv(p)
    said = str(e.value)
    assert "bad_cycle.csv" in said and (f"row {row}:" in said or f"row {row}, column " in said if row else "at least 2" in said)


@pytest.mark.parametrize("body,expect", [
    # the quoted field took the line break and the next row, csv_number stripped it: read as 0,0 1,2 3,4
    ('time_s,speed_kmh\n0,0\n1,"2\n"\n3,4\n', "row 3: a field runs over a line break into row 4"),
    ('time_s,speed_kmh\n0,0\n1,"2', "row 3: a quote left open (the file ends inside its field)"),
])
def test_a_field_over_a_line_break_or_a_quote_left_open_is_refused(tmp_path, body, expect):
    p = tmp_path / "quoted.csv"
    p.write_text(body)
    with pytest.raises(ValueError, match=f"quoted\\.csv: {re.escape(expect)}"):
        read_cycle_csv(p)


def test_csv_roundtrip(tmp_path):
    p = tmp_path / "mine.csv"
    p.write_text("time_s,speed_kmh\n0,0\n10,36\n20,0\n")
    c = load_cycle(str(p))
    assert c.name == "mine" and c.distance_m == pytest.approx(100.0)


def test_csv_saved_by_excel_with_a_bom_and_crlf(tmp_path):
    """Excel's "CSV UTF-8" starts with a byte-order mark; it made the header 'not time_s,speed_kmh'."""
    p = tmp_path / "excel.csv"
    p.write_bytes(b"\xef\xbb\xbftime_s,speed_kmh\r\n0,0\r\n10,36\r\n20,0\r\n")
    c = load_cycle(str(p))
    assert c.name == "excel" and c.distance_m == pytest.approx(100.0)


def test_csv_not_utf8_names_the_file(tmp_path):
    p = tmp_path / "latin1.csv"
    p.write_bytes("time_s,speed_kmh\n0,0\n1,1\xe9\n".encode("latin-1"))
    with pytest.raises(ValueError, match=r"latin1\.csv: not a UTF-8 text CSV"):
        read_cycle_csv(p)


def test_csv_field_beyond_the_csv_limit_is_one_line(tmp_path):
    """_csv.Error escaped read_cycle_csv: bev-mdo evaluate printed a traceback."""
    p = tmp_path / "huge.csv"
    p.write_text("time_s,speed_kmh\n0,0\n1," + "1" * 200_000 + "\n")
    with pytest.raises(ValueError, match=r"huge\.csv: row 3: not a CSV table: field larger"):
        read_cycle_csv(p)


def test_a_csv_too_long_or_too_big_is_refused_before_its_rows_fill_memory(tmp_path, monkeypatch):
    """A valid 3,000,000-row trace (52 MB) was read whole and took 1.6 GB, then a MemoryError (exit 7)
    under a memory limit; the 48 h bound applies only after reading, and a trace may be sampled finely."""
    monkeypatch.setattr(cycles, "MAX_CSV_ROWS", 100)
    p = tmp_path / "long.csv"
    p.write_text("time_s,speed_kmh\n" + "".join(f"{0.05 * i:.2f},10\n" for i in range(100)))
    with pytest.raises(ValueError, match=r"long\.csv: more than 100 rows, more than a drive cycle may have"):
        read_cycle_csv(p)
    p.write_text("time_s,speed_kmh\n" + "".join(f"{0.05 * i:.2f},10\n" for i in range(99)))
    assert len(read_cycle_csv(p).time_s) == 99
    monkeypatch.setattr(cycles, "MAX_CSV_BYTES", 100)
    with pytest.raises(ValueError, match=r"long\.csv: \d+ bytes, more than a drive cycle may be \(100 bytes"):
        read_cycle_csv(p)


def test_unknown_cycle_name():
    with pytest.raises(ValueError, match="unknown drive cycle"):
        load_cycle("ftp75")


def test_resample_pchip_reproduces_linear_trace_and_derivatives():
    c = DriveCycle("ramp", np.array([0.0, 10.0]), np.array([0.0, 5.0]))
    r = resample(c, 0.5, "pchip")
    assert r.time_s[-1] == pytest.approx(10.0) and len(r.time_s) == 21
    np.testing.assert_allclose(r.speed_m_s, 0.5 * r.time_s, atol=1e-12)
    np.testing.assert_allclose(r.accel_m_s2, 0.5, atol=1e-12)
    np.testing.assert_allclose(r.jerk_m_s3, 0.0, atol=1e-12)


def test_resample_nedc_pchip_keeps_distance_and_is_cached():
    r = resample(nedc(), 1.0, "pchip")
    assert r.distance_m == pytest.approx(nedc().distance_m)
    assert resample(nedc(), 1.0, "pchip") is r
    assert np.min(r.speed_m_s) >= 0.0  # pchip is shape preserving: no undershoot at stops


def test_resample_spline_smooths():
    c = nedc()
    rough = resample(c, 1.0, "spline", smoothing=0.0)
    smooth = resample(c, 1.0, "spline", smoothing=10.0)
    assert np.abs(smooth.jerk_m_s3).max() < np.abs(rough.jerk_m_s3).max()
    assert smooth.distance_m == pytest.approx(c.distance_m, rel=5e-3)


@pytest.mark.parametrize("kw,name", [({"dt_s": 0.0}, "dt_s"), ({"method": "cubic"}, "interpolation"),
                                     ({"smoothing": -1.0}, "smoothing")])
def test_resample_bad_arguments(kw, name):
    with pytest.raises(ValueError, match=name):
        resample(nedc(), **kw)


def test_a_trace_that_does_not_end_at_its_start_speed_gets_a_note():
    """A segment cut from a log at speed gains or loses kinetic energy over the trace: the note says
    which way energies per km are off and by about how much (1/2 M (v1^2 - v0^2) per km)."""
    for name in cycles.CYCLE_NAMES:
        assert cycles.unbalanced_note(load_cycle(name), name) is None
    up = DriveCycle("up", np.array([0.0, 100.0]), np.array([10.0, 20.0]))  # 1.5 km
    note = cycles.unbalanced_note(up, "up.csv")
    expect = 0.5 * 1500 * (20.0**2 - 10.0**2) / 3600 / 1.5
    assert "gains" in note and "overstated" in note and f"{expect:.1f} Wh/km" in note
    down = DriveCycle("down", np.array([0.0, 100.0]), np.array([20.0, 10.0]))
    assert "understated" in cycles.unbalanced_note(down, "down.csv")
    same = DriveCycle("same", np.array([0.0, 50.0, 100.0]), np.array([15.0, 20.0, 15.0]))
    assert cycles.unbalanced_note(same, "same.csv") is None
