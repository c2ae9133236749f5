"""`bev-mdo resume BAG`: restart an interrupted optimisation from its last recorded iterate, a finished
one from its result (with --starts, or an earlier best point, not its last record), or optimise from
the best design of a sweep's bag.

The configuration comes from the bag itself (stored by the recorder), so the bag is
all that is needed. The resumed run is recorded to a new bag.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from bev_mdo.cli.flags import add_bag_argument


def register(sub) -> None:
    p = sub.add_parser("resume", description="Read the run's configuration and its last IterationRecord from BAG and "
                                   "optimise again from that design (a truncated bag works too); from a "
                                   "finished run's bag, from its result; from a sweep's bag, from its best "
                                   "design (feasible, else least violated).")
    add_bag_argument(p)
    p.add_argument("--json", action="store_true")
    p.add_argument("--output", dest="out_bag", default=None, help="bag to write (default: bags/<config name>_<time>_<run>, as optimize)")
    p.add_argument("--quiet", action="store_true")
    p.add_argument("--run-id", default=None,
                   help="the run to resume (default: the bag's own; needed for a recording of several runs)")
    from bev_mdo.cli.history import add_verify_arguments

    add_verify_arguments(p)
    from bev_mdo.cli.flags import add_layout_arguments, add_transport_arguments

    add_layout_arguments(p)  # as optimize: by default the nodes in this process (--compose coordinator)
    add_transport_arguments(p, attach=False, record="do not record the resumed run (as optimize --no-record)")
    p.set_defaults(func=run)


def resume_point(bag_path: str, run_id: str | None = None, key_file: str | None = None,
                 checks: dict | None = None, no_verify: bool = False) -> tuple:
    """(the run's RunConfig, last verified design of the bag's own run, its iteration) from a bag;
    BagError (a ValueError) if there is none or it cannot be verified."""
    from bev_mdo.bag.history import last_iterate
    from bev_mdo.bag.reader import open_bag
    from bev_mdo.config import RunConfig
    from bev_mdo.yamlload import load_yaml

    bag = open_bag(bag_path)
    if bag.truncated:  # resumed from what was read, as history and report do
        print(bag.recovery_note(), file=sys.stderr)
    config_yaml, design, iteration = last_iterate(bag, run_id, key_file, checks, no_verify)
    if not config_yaml:
        raise ValueError(f"{bag_path}: the bag holds no configuration; cannot resume")
    try:
        stored = load_yaml(config_yaml)
    except ValueError as exc:  # e.g. a cycle trace recorded whole past the YAML limit, before that was refused
        raise ValueError(f"{bag_path}: the bag's configuration cannot be read back ({exc}); cannot resume") from None
    config = RunConfig.load(stored, where=f"{bag_path} (its stored config)")
    fixed = json.loads(bag.info.get("fixed") or "{}")  # a sweep's --set values: held in the resumed run
    if fixed and checks is not None:
        config = held(config, fixed)
        checks["fixed"] = "keeping what the sweep fixed with --set: " + ", ".join(f"{k}={v:g}" for k, v in fixed.items())
    return config, design, iteration


def held(config, fixed: dict):
    """``config`` with the ``fixed`` values held: a design variable among them leaves the optimisation and,
    as every other name, goes into ``problem.parameters`` (a constant input of every evaluation)."""
    problem = dict(config["problem"])
    dvs = {k: v for k, v in problem["design_variables"].items() if k not in fixed}
    if not dvs:
        raise ValueError("the sweep fixed every design variable with --set: nothing left to optimise")
    base = problem.get("baseline")
    if base and base.get("design"):  # evaluated with the held values too: its name says so
        held_text = ", ".join(f"{k}={v:g}" for k, v in fixed.items())
        problem["baseline"] = {**base, "design": {k: v for k, v in base["design"].items() if k not in fixed},
                               "name": f"{base.get('name') or 'baseline'} with {held_text} held"}
    problem.update(design_variables=dvs, parameters={**(problem.get("parameters") or {}), **fixed})
    return config.with_sections(problem=problem)


def is_per_run_key(path) -> bool:
    """Whether `path` is a per-run key bev-mdo created for a run (``<bag's parent>/.keys/<bag name>/sign.key``,
    auth.with_run_key), not a key file the user configured."""
    return bool(path) and Path(str(path)).name == "sign.key" and Path(str(path)).parent.parent.name == ".keys"


def run(args) -> int:
    from bev_mdo.api.transport import Transport
    from bev_mdo.bag.history import check_note
    from bev_mdo.cli.optimize import run_job
    from bev_mdo.config import RunConfig

    if args.out_bag and not args.no_record:  # named by its own flag (optimize's check says --bag)
        from bev_mdo.api.runbag import check_new_bag

        check_new_bag(Path(args.out_bag), "--output")
    checks: dict = {}
    config, design, iteration = resume_point(args.bag, args.run_id, args.key_file, checks, args.no_verify)
    out = sys.stderr if args.json else sys.stdout
    if check_note(checks):
        print(f"{args.bag}: {check_note(checks)}", file=sys.stderr)
    if checks.get("fixed"):
        print(checks["fixed"], file=out)
    # the resumed run gets a key of its own (the old path would make the new run share the old key)
    config = RunConfig.of(config)
    if is_per_run_key(config["ros"].get("sign_key_file")):
        config = config.with_ros({**config["ros"], "sign_key_file": ""})
    problem = config.problem
    if isinstance(design, list):  # an interrupted multi-start: every start goes on from its own last record
        print(f"resuming {config.name} from {checks['starts']}", file=out)
        x0 = _start_points(problem, design, checks.get("seed"), out)
        x0 = [_in_bounds(config, problem, x, out) for x in x0]
    else:
        print(f"resuming {config.name} from {checks.get('sweep') or checks.get('result') or f'iteration {iteration}'} "
              "at " + ", ".join(f"{k}={v:.6g}" for k, v in design.items()), file=out)
        x0 = _in_bounds(config, problem, design, out)
    opts = argparse.Namespace(**vars(Transport.of(args)), formulation=None, optimizer=None, json=args.json,
                              bag=args.out_bag, bag_flag="--output", no_record=args.no_record, quiet=args.quiet,
                              instances=args.instances, compose=args.compose)
    return run_job(config, opts, x0=x0)


def _start_points(problem, designs: list, seed, out) -> list[dict]:
    """Each start's design; a start with no record gets its point of the sample again (its seed), or is
    left out when the sample is not known (the run was itself resumed from given points)."""
    missing = [i for i, d in enumerate(designs) if d is None]
    if missing and seed is not None:
        from bev_mdo.mdo.multistart import start_points

        sample = start_points(problem, len(designs), seed)
        designs = [sample[i] if d is None else d for i, d in enumerate(designs)]
    elif missing:
        from bev_mdo.bag.history import few

        print(f"left out {len(missing)} start(s) ({few([i + 1 for i in missing], 10)}): no record of them and no "
              "sample to draw their points from", file=out)
    designs = [d for d in designs if d is not None]
    if not designs:
        raise ValueError("no start of the multi-start has a record to resume from")
    return designs


def _in_bounds(config, problem, design: dict, out) -> dict:
    """The design variables (element names such as 'x_shared[0]' for vectors, as the bag records them) of
    a recorded design and, for IDF, its couplings, within their bounds: an optimiser may end a little
    outside a bound (COBYLA, trust-constr: within the feasibility tolerance), and the resumed run then
    starts on the bound instead of refusing its start point."""
    names = problem.names
    x0 = {k: v for k, v in design.items() if k in names}
    if str(config["formulation"]).lower() == "idf":  # IDF goes on from the couplings it held, too
        x0.update({k: v for k, v in design.items() if k not in names})
    lo, hi = (dict(zip(names, problem.array(side))) for side in ("lower", "upper"))
    for k in set(x0) - set(names):
        lo[k], hi[k] = problem.coupling_bound(k)
    moved = {k: min(max(v, lo[k]), hi[k]) for k, v in x0.items() if not lo[k] <= v <= hi[k]}
    if moved:
        print("starting on the bound of " + ", ".join(  # "(20 -> 20)" was 19.9999999997 put on its bound 20
            f"{k} (recorded {x0[k]:.12g}, {abs(x0[k] - v):.3g} {'below its lower' if x0[k] < v else 'above its upper'} "
            f"bound {v:.12g})" for k, v in moved.items()), file=out)
        x0.update(moved)
    return x0
