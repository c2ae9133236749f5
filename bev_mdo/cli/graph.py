"""``bev-mdo graph CONFIG [--png FILE] [--dot FILE]``: the coupling graph of a run.

An N² chart (design structure matrix): the optimiser and the disciplines on the diagonal in
execution order; the cell in row A, column B lists what A passes to B (above the diagonal:
feed-forward, below it: feedback, i.e. a loop the MDA must converge). The optimiser's row holds
the design variables it drives, its column the objective and constraints it reads. The same as
Graphviz DOT text (``dot -Tpng graph.dot -o graph.png`` renders it where Graphviz is installed).
"""
from __future__ import annotations

import sys
import textwrap
from bev_mdo.figures import subplots

OPT = "optimizer"


def register(sub) -> None:
    p = sub.add_parser("graph", description="Disciplines, their couplings, feedback loops and what the optimiser "
                                            "drives, from the run config (no ROS needed). Without --png/--dot the DOT "
                                            "text goes to stdout.")
    p.add_argument("config", help="run config YAML")
    p.add_argument("--png", metavar="FILE", help="write the N² chart here")
    p.add_argument("--dot", metavar="FILE", help="write Graphviz DOT text here ('-' or /dev/stdout for stdout)")
    p.set_defaults(func=run)


def coupling_model(config) -> dict:
    """{order: [optimizer, disciplines...], edges: {(a, b): [vars]}, loops: [[names]], external: {...}}."""
    from bev_mdo.config import RunConfig
    from bev_mdo.mdo.graph import CouplingGraph

    config = RunConfig.of(config)
    problem, discs = config.problem, config.disciplines
    specs = [(d.name, tuple(d.inputs), tuple(d.outputs)) for d in discs]
    g = CouplingGraph(specs)
    order = [n for comp in g.components for n in comp]
    edges: dict[tuple[str, str], list[str]] = {}
    dvs = set(problem.names)
    for b in order:
        for v in g.inputs[b]:
            if v in g.producer:
                edges.setdefault((g.producer[v], b), []).append(v)
            elif v in dvs:
                edges.setdefault((OPT, b), []).append(v)
    responses = [problem.objective] + [c.name for c in problem.constraints]
    for v in responses:
        if v in g.producer:
            edges.setdefault((g.producer[v], OPT), [])
            if v not in edges[(g.producer[v], OPT)]:
                edges[(g.producer[v], OPT)].append(v)
    params = sorted(set(g.external_inputs) - dvs)
    consumed = {v for i in g.inputs.values() for v in i} | set(responses)
    unused = {n: [v for v in g.outputs[n] if v not in consumed] for n in order}
    return {"order": [OPT] + order, "edges": edges, "loops": [list(c) for c in g.cycles],
            "objective": problem.objective, "constraints": [c.name for c in problem.constraints],
            "design_variables": problem.names, "parameters": params, "formulation": config.settings.formulation,
            "limits": {c.name: " ".join(x for x in ((f"≥ {c.lower:g}" if c.lower is not None else ""),
                                                    (f"≤ {c.upper:g}" if c.upper is not None else "")) if x)
                       for c in problem.constraints},
            "unused": {n: v for n, v in unused.items() if v}}


def to_dot(model: dict, name: str = "bev_mdo") -> str:
    """Graphviz DOT text of the coupling model."""
    pos = {n: i for i, n in enumerate(model["order"])}
    lines = [f'digraph "{name}" {{', "  rankdir=LR;", '  node [shape=box, style="rounded,filled", fillcolor="#e8eef7"];',
             f'  {OPT} [shape=ellipse, fillcolor="#f7e3c6", label="{OPT}\\n({model["formulation"].upper()}; '
             f'min {model["objective"]})"];']
    for n in model["order"][1:]:
        lines.append(f'  "{n}";')
    for k, loop in enumerate(model["loops"]):
        lines.append(f"  subgraph cluster_loop{k} {{ label=\"feedback loop (MDA)\"; style=dashed; "
                     + " ".join(f'"{n}";' for n in loop) + " }")
    for (a, b), vs in model["edges"].items():
        style = ', style=dashed, color="#c0392b"' if a != OPT and b != OPT and pos[a] > pos[b] else ""
        label = "\\n".join(vs)
        lines.append(f'  "{a}" -> "{b}" [label="{label}"{style}];')
    lines.append("}")
    return "\n".join(lines) + "\n"


def plot_n2(model: dict, path, title: str = ""):
    """Draw the N² chart; returns the matplotlib figure."""
    from matplotlib.patches import Rectangle

    order = model["order"]
    n = len(order)
    pos = {k: i for i, k in enumerate(order)}
    size = max(6.0, 1.9 * n)
    fig, ax = subplots(figsize=(size, size * 0.85))
    for i, k in enumerate(order):
        colour = "#f7e3c6" if k == OPT else "#c9d9f0"
        ax.add_patch(Rectangle((i, i), 1, 1, facecolor=colour, edgecolor="k"))
        label = k.replace("_", "\n") if k != OPT else f"optimizer\n{model['formulation'].upper()}"
        ax.text(i + 0.5, i + 0.55, label, ha="center", va="center", fontsize=9, weight="bold")
        if model["unused"].get(k):
            ax.text(i + 0.5, i + 0.88, "out, unused:\n" + "\n".join(model["unused"][k]), ha="center",
                    va="center", fontsize=6, color="0.3")
    for (a, b), vs in model["edges"].items():
        i, j = pos[a], pos[b]
        feedback = a != OPT and b != OPT and i > j
        colour = "#f5c6c0" if feedback else ("#fbeedd" if OPT in (a, b) else "#eef3fa")
        ax.add_patch(Rectangle((j, i), 1, 1, facecolor=colour, edgecolor="0.5"))
        if b == OPT:
            vs = [f"{v}\n(objective)" if v == model["objective"] else f"{v}\n{model['limits'].get(v, '')}".strip()
                  for v in vs]
        ax.text(j + 0.5, i + 0.5, "\n".join(vs), ha="center", va="center", fontsize=7)
    for loop in model["loops"]:
        idx = [pos[k] for k in loop]
        lo, hi = min(idx), max(idx) + 1
        ax.add_patch(Rectangle((lo, lo), hi - lo, hi - lo, fill=False, edgecolor="#c0392b", lw=2, ls="--"))
    ax.set_xlim(0, n)
    ax.set_ylim(n, 0)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    loops = "; feedback loops: " + ", ".join("+".join(l) for l in model["loops"]) if model["loops"] else \
        "; no feedback loop (feed-forward)"
    text = ((title + "\n" if title else "") + "N² chart: row passes to column; first row: what the optimiser "
            "drives, first column: what it reads;\nbetween disciplines, above the diagonal feed-forward, "
            "below it feedback (red)" + loops)
    chars = int(size * 72 / (0.6 * 9))  # the figure's width in characters of the 9 pt title (DejaVu Sans)
    ax.set_title("\n".join(textwrap.fill(line, chars) for line in text.splitlines()), fontsize=9)
    fig.tight_layout()
    from bev_mdo.cli import save_figure

    save_figure(fig, path)
    return fig


def run(args) -> int:
    from bev_mdo.cli import figure_format, is_stdout, write_text_file
    from bev_mdo.config import RunConfig

    if args.png:
        figure_format(args.png)  # a folder or standard output: refused first
    config = RunConfig.load(args.config)
    model = coupling_model(config)
    dot = to_dot(model, config.name)
    if args.png:
        plot_n2(model, args.png, title=f"{config.name}: coupling graph")
        print(f"wrote {args.png}", file=sys.stderr)
    if args.dot and not is_stdout(args.dot):
        write_text_file(args.dot, dot)
        print(f"wrote {args.dot}", file=sys.stderr)
    elif args.dot or not args.png:
        sys.stdout.write(dot)
    return 0
