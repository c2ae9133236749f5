

def test_the_first_error_line_is_cut_between_points_not_inside_a_word():
    """The console's 'discipline failed' line and discipline_errors were cut at 300 characters,
    mid-word ('... at poin')."""
    from bev_mdo.mdo.discipline import first_error_line

    parts = [f"d: non-finite output ['y'] at point {i} (x={i})" for i in range(20)]
    line = first_error_line("; ".join(parts) + "\nTraceback ...")
    assert line.endswith(" ...") and len(line) <= 304 and line[:-4] == "; ".join(parts[:line.count("; ") + 1])
    assert first_error_line("short one\nmore") == "short one" and first_error_line("x" * 400) == "x" * 300 + " ..."
