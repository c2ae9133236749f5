"""`bev-mdo graph`: the coupling model, DOT text and the N² chart (inspected, not looked at)."""
from __future__ import annotations

from pathlib import Path

import yaml

from bev_mdo.cli.graph import OPT, coupling_model, plot_n2, to_dot
from bev_mdo.config import load_config

ROOT = Path(__file__).resolve().parents[2]


def _config(sized: bool = False):
    raw = yaml.safe_load((ROOT / "config/leaf_nedc.yaml").read_text())
    raw["problem"]["battery_sized_for_range"] = sized
    return load_config(raw)


def test_default_graph_is_feed_forward_and_names_what_the_optimiser_drives_and_reads():
    m = coupling_model(_config())
    assert m["loops"] == []
    assert m["order"][0] == OPT
    assert m["edges"][("vehicle_mass", "energy")] == ["vehicle_mass_kg"]
    assert m["edges"][("energy", "range")] == ["energy_wh_per_km"]
    driven = {v for (a, _), vs in m["edges"].items() if a == OPT for v in vs}
    assert driven == {"motor_kw", "gear_ratio", "battery_kwh"}
    read = {v for (_, b), vs in m["edges"].items() if b == OPT for v in vs}
    assert read == {"energy_wh_per_km", "range_km", "motor_speed_max_rad_s", "accel_time_0_100_s"}
    assert m["unused"] == {"cost": ["powertrain_cost_usd"]}


def test_battery_sizing_makes_a_feedback_loop_shown_in_dot_and_chart(tmp_path):
    m = coupling_model(_config(sized=True))
    assert len(m["loops"]) == 1 and set(m["loops"][0]) == {"vehicle_mass", "energy", "battery_sizing"}
    pos = {n: i for i, n in enumerate(m["order"])}
    feedback = [(a, b) for (a, b) in m["edges"] if OPT not in (a, b) and pos[a] > pos[b]]
    assert feedback, "a loop needs an edge below the diagonal"
    dot = to_dot(m)
    assert dot.startswith('digraph "bev_mdo" {') and dot.rstrip().endswith("}")
    assert "cluster_loop0" in dot and "style=dashed" in dot
    fig = plot_n2(m, tmp_path / "n2.png")
    texts = [t.get_text() for t in fig.axes[0].texts]
    assert "battery\nsizing" in texts
    assert any(t.startswith("range_km\n≥ 170") for t in texts)
    assert (tmp_path / "n2.png").stat().st_size > 1000


def test_png_without_extension_or_into_a_directory(tmp_path, capsys):
    """'wrote graph' was printed while matplotlib wrote graph.png; --png DIR wrote DIR.png beside it."""
    from bev_mdo.cli import main

    plain = tmp_path / "graph"
    assert main(["graph", str(ROOT / "config/leaf_nedc.yaml"), "--png", str(plain)]) == 0
    assert plain.read_bytes()[:4] == b"\x89PNG" and not plain.with_suffix(".png").exists()
    assert main(["graph", str(ROOT / "config/leaf_nedc.yaml"), "--png", str(tmp_path)]) == 2
    assert "is a directory" in capsys.readouterr().err and not tmp_path.with_suffix(".png").exists()


def test_the_title_fits_the_figure(tmp_path):
    """The N² chart's title (three long lines) was wider than the figure for small graphs."""
    from bev_mdo.config import load_config as load

    for config in (ROOT / "examples/sensitivity/ishigami.yaml", ROOT / "examples/sellar/sellar_mdf.yaml",
                   ROOT / "config/leaf_nedc.yaml"):
        fig = plot_n2(coupling_model(load(config)), tmp_path / "n2.png", title="a run's coupling graph")
        from matplotlib.backends.backend_agg import FigureCanvasAgg

        canvas = FigureCanvasAgg(fig)  # the saved figure, drawn again to measure it
        canvas.draw()
        renderer = canvas.get_renderer()
        box = fig.axes[0].title.get_window_extent(renderer)
        assert box.x0 >= 0 and box.x1 <= fig.bbox.x1 and box.y1 <= fig.bbox.y1, (config, box, fig.bbox)
