"""Command-line flags shared by several commands: ROS discovery and transport (their meaning:
bev_mdo.api.transport) and the problem overrides (bev_mdo.api.overrides)."""
from __future__ import annotations

import argparse
import math
import re


def seed(text: str) -> int:
    """The type of every ``--seed``: a whole number >= 0 (models.common.check_seed, as the Python API's)."""
    from bev_mdo.models.common import check_seed

    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    try:
        return check_seed(value)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_bag_argument(parser) -> None:
    """The BAG of every command that reads one (bag info/repair, history, report, replay, resume); what it
    may name is bev_mdo.bag.reader.find_mcap's."""
    parser.add_argument("bag", help="bag directory, its .mcap file, or a run's output folder holding one bag")


def add_ros_arguments(parser, config: bool = True) -> None:
    """The discovery flags shared by commands that join a ROS graph (they override the config's ros: section;
    ``config=False``: a command that takes no config, replay)."""
    section = "the config's ros: section; " if config else ""
    g = parser.add_argument_group(f"ROS discovery (default: {section}localhost only)")
    first = "the config's ros.domain_id if it sets one, else " if config else ""
    g.add_argument("--domain-id", type=int, default=None,
                   help=f"ROS domain id (default: {first}ROS_DOMAIN_ID, else 77)")
    g.add_argument("--discovery", choices=["localhost", "static_peers", "server", "subnet"], default=None,
                   help="how nodes find each other; anything but localhost is an explicit opt-in to other hosts")
    g.add_argument("--static-peers", default=None, metavar="IP[,IP...]", help="with --discovery static_peers")
    g.add_argument("--discovery-server", default=None, metavar="IP:PORT", help="with --discovery server")


def join_domain(args, where: str | None = "record") -> None:
    """Domain and discovery of a recording or a replay: the flags, over the --config file's ros: section (record's),
    else a valid ROS_DOMAIN_ID of the environment (localhost by default: never off-host unasked). A bad value is
    said after the file's name, or ``where`` (None: as it is)."""
    import os
    from pathlib import Path

    from bev_mdo.api.transport import ros_section
    from bev_mdo.ros.client import apply_ros_environment

    ros, env = {}, os.environ.get("ROS_DOMAIN_ID", "")
    if getattr(args, "config", None):
        from bev_mdo.yamlload import load_yaml

        try:
            raw = load_yaml(Path(args.config).read_text(encoding="utf-8"))
        except Exception as exc:  # yaml.YAMLError and friends: one line naming the file
            raise ValueError(f"{args.config}: not valid YAML: {str(exc).splitlines()[0]}") from None
        ros = (raw.get("ros") or {}) if isinstance(raw, dict) else {}
    if "domain_id" not in ros and env.isdigit():
        ros = {"domain_id": int(env), **ros}
    try:
        apply_ros_environment(ros_section({"ros": ros}, args))
    except ValueError as exc:
        if not (getattr(args, "config", None) or where):
            raise
        raise ValueError(f"{getattr(args, 'config', None) or where}: {exc}") from None


def add_transport_arguments(parser, attach: bool = True, record: str | None = "") -> None:
    """The transport flags of every command that evaluates designs (optimize, resume, evaluate, sweep,
    compare, sensitivity, check-totals, pareto), with the discovery flags; their meaning and their one
    default: bev_mdo.api.transport.Transport. ``attach=False``: a command that always starts its own
    nodes (optimize, resume, pareto: bound to their run and recorder) does not offer ``--attach`` and
    refuses it at once with one line saying why (not argparse's 'unrecognized arguments').

    ``--no-record``, the same on every one of them: ``record`` is its help where the command writes a bag
    it can leave out (optimize, resume, sweep); "" (a command that never records: evaluate, compare,
    sensitivity, check-totals) takes it and does nothing, as asked, without offering it in its help;
    None (pareto, whose front is its bag) refuses it in one line saying why."""
    from bev_mdo.api.transport import DEFAULT_TRANSPORT, TRANSPORTS, attach_refused

    class Refuse(argparse.Action):
        def __call__(self, parser, namespace, values, option_string=None):
            command = parser.prog.split()[-1]
            why = attach_refused(command) if option_string == "--attach" else (
                f"{command} --no-record: {command} always records its fronts, one per generation, in its bag "
                "(OUT/bag); drop --no-record")
            parser.exit(2, f"{parser.prog}: error: {why}\n")

    if record is None:
        parser.add_argument("--no-record", nargs=0, action=Refuse, dest="refused", default=argparse.SUPPRESS,
                            help=argparse.SUPPRESS)
    else:
        parser.add_argument("--no-record", action="store_true", help=record or argparse.SUPPRESS)

    g = parser.add_argument_group("transport")
    g.add_argument("--transport", choices=TRANSPORTS, default=DEFAULT_TRANSPORT,
                   help="ros (default): the config's discipline nodes, started for this command on its domain "
                        "and stopped after, signed with a per-run key; inprocess: the same disciplines in this "
                        "process, no ROS")
    if attach:
        g.add_argument("--attach", action="store_true",
                       help="ROS: use the discipline nodes already running on the domain (ros2 run, bev-mdo node) "
                            "instead of starting this command's own")
    else:
        g.add_argument("--attach", nargs=0, action=Refuse, dest="refused", default=argparse.SUPPRESS,
                       help=argparse.SUPPRESS)
    add_ros_arguments(parser)


def add_layout_arguments(parser, compose: bool = True) -> None:
    """Where a run's discipline nodes run over ROS, for the commands that start their own (optimize,
    resume; pareto without ``compose``): ``--instances`` (pools) and ``--compose`` (default coordinator)."""
    parser.add_argument("--instances", default=None, metavar="N|NAME=N,...",
                        help="ROS: run N instances of every discipline, or of the named ones; they share each "
                             "batch (ros.pool: share) or all answer it (redundant; docs/scaling.md)")
    if compose:
        parser.add_argument("--compose", default="coordinator", metavar="coordinator|none|all|A+B,C+D",
                            help="ROS: where the discipline nodes run. coordinator (default): in this command's "
                                 "own process, beside the coordinator (a pool's instances keep a process each); "
                                 "none: a process per discipline; all: one process for all; groups A+B,C+D "
                                 "(docs/scaling.md)")


def add_override_arguments(parser, single_objective: bool = True) -> None:
    """The problem overrides; ``single_objective=False`` (pareto: its objectives are --objectives, its
    population is sampled over the bounds) leaves out --initial, --objective and --maximize/--minimize."""
    g = parser.add_argument_group("problem overrides (applied to the config before it is checked and recorded)")
    g.add_argument("--bound", action="append", default=[], metavar="NAME=LO:HI",
                   help="bounds of a design variable; LO or HI may be left out (motor_kw=:100)")
    g.add_argument("--constraint", action="append", default=[], metavar="'NAME>=X'",
                   help="add or change a constraint on an output: 'range_km>=250' or 'accel_time_0_100_s<=9'")
    if not single_objective:
        return
    g.add_argument("--initial", action="append", default=[], metavar="NAME=X", help="initial value of a design variable")
    g.add_argument("--objective", default=None, metavar="NAME", help="the output to optimise")
    sense = g.add_mutually_exclusive_group()
    sense.add_argument("--maximize", action="store_true", default=None, help="maximise the objective")
    sense.add_argument("--minimize", dest="maximize", action="store_false", help="minimise the objective")


def parse_assignments(items: str | list[str], flag: str = "--set") -> dict[str, float]:
    """``["a=1,b=2", "c=3"]`` (or one such string) -> {a: 1.0, b: 2.0, c: 3.0}: the NAME=VALUE lists of
    --set, --design and --at; an InputError naming `flag` on a malformed item."""
    from bev_mdo.api.errors import InputError
    from bev_mdo.api.overrides import no_underscore

    def one_number(name: str, given: str):  # a list given to a name: [9.04,4.7] or 9.04,4.7
        two = (" (a two-speed gearbox is gear_count=2 with gear_ratio_2 for its second gear: "
               f"{flag} gear_count=2,gear_ratio=9.04,gear_ratio_2=4.7)" if name.startswith("gear_ratio") else "")
        return InputError(f"{flag} {name}={given}: {flag} takes one number per name (NAME=VALUE){two}")

    out: dict[str, float] = {}
    for item in [items] if isinstance(items, str) else items:
        last, parts = "", [s.strip() for s in item.split(",")]
        if "" in parts[:-1]:  # motor_kw=200,,battery_kwh=50 was taken as if the empty item were not (a last comma is)
            raise InputError(f"{flag} {item.strip()!r}: an empty item between commas; give NAME=VALUE,NAME=VALUE")
        for part in filter(None, parts):
            name, sep, value = part.partition("=")
            bare = re.fullmatch(r"[-+.\d\s\]\)eE]+|[-+]?(nan|inf|infinity)[\s\]\)]*", part, re.IGNORECASE)
            if not sep and last and bare:  # gear_ratio=9.04,4.7 (or 200,nan)
                raise one_number(last, f"{out[last]:g},{part}")
            if not sep or not name.strip():
                raise InputError(f"{flag} {part!r} must be NAME=VALUE, e.g. motor_kw=80")
            if name.strip() in out:  # the last one used to win silently
                raise InputError(f"{flag} {name.strip()}: given twice ({out[name.strip()]:g} and {value.strip()})")
            if value.strip()[:1] in ("[", "("):  # gear_ratio=[9.04,4.7]
                raise one_number(name.strip(), item[item.index(part) + len(name) + 1:].strip())  # the rest of it
            if "=" in value:  # motor_kw=80;gear_ratio=8 was "an underscore in a number is taken for a typo"
                raise InputError(f"{flag} {part!r}: two NAME=VALUE in one item; separate them by commas")
            no_underscore(value, f"{flag} {name.strip()}={value.strip()}")
            try:
                out[name.strip()] = number = float(value)
            except ValueError:
                raise InputError(f"{flag} {name.strip()}={value!r}: value must be a number") from None
            if not math.isfinite(number):  # named as typed: 1e400 was said as inf
                raise InputError(f"{flag} {name.strip()}={value.strip()}: a design value must be a finite number")
            last = name.strip()
    return out


def load_config(args):
    """The validated config (``RunConfig``) of ``args.config`` with the command line's overrides."""
    from bev_mdo.api.overrides import from_args, load

    return load(args.config, from_args(args))
