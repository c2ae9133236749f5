"""Which node processes a run starts, as command lines: the node executables (``ros2 run bev_mdo
<exe>``), one discipline's or a composed group's argv, the ROS node names an argv runs, and the
``--instances``/``--compose`` plans. Plain Python (no rclpy): the launcher, the sessions, the API and
the coordinator (for ``--compose coordinator``) read it.
"""
from __future__ import annotations

import sys
from typing import Mapping, Sequence

# executable -> built-in discipline name it serves (None: not a discipline node)
DISCIPLINE_EXES = {
    "vehicle_mass_node": "vehicle_mass",
    "energy_node": "energy",
    "range_node": "range",
    "acceleration_node": "acceleration",
    "motor_speed_node": "motor_speed",
    "cost_node": "cost",
}
OTHER_EXES = ("discipline_node", "coordinator_node", "recorder_node", "composed_node")
_BUILTIN_EXE = {v: k for k, v in DISCIPLINE_EXES.items()}


def discipline_argv(name: str, config_path: str, instance: str = "", run_id: str = "") -> list[str]:
    """Command line of the node serving discipline `name` (built-in exe or the generic node).

    With `run_id` the node serves only that run (and its ``<run>-...`` sub-runs)."""
    exe = _BUILTIN_EXE.get(name, "discipline_node")
    argv = [sys.executable, "-m", "bev_mdo.ros.run", exe, "--ros-args", "-p", f"config:={config_path}"]
    if exe == "discipline_node":
        argv += ["-p", f"discipline:={name}"]
    node_name = f"{name}_node" + (f"_{instance}" if instance else "")
    argv += ["-r", f"__node:={node_name}"]
    # quoted: a hex run id of digits only ("1234...") would otherwise be parsed as a number
    if instance:
        argv += ["-p", f"instance:='{node_name}'"]
    if run_id:
        argv += ["-p", f"run_id:='{run_id}'"]
    return argv


MEANT_FOR = {"discipline": "discipline_node", "disciplines": "composed_node"}  # given to another node: named


def check_parameters(given, declared, node: str) -> None:
    """ValueError naming the first parameter given to `node` (``-p``, a parameters file) that it does not
    declare, with the declared ones closest to it: rclpy keeps such an override without a word, so a
    misspelt ``vehicle.drag_aera_m2`` left the node serving the config's value."""
    import difflib

    declared = sorted(str(d) for d in declared)
    for name in sorted(set(map(str, given)) - set(declared)):
        pre = "vehicle." if name.startswith("vehicle.") else ""  # compared on the key, not the shared prefix
        near = [pre + m for m in difflib.get_close_matches(name[len(pre):], [d[len(pre):] for d in declared
                                                                            if d.startswith(pre)], n=3, cutoff=0.6)]
        vehicle = any(d.startswith("vehicle.") for d in declared)  # a discipline node's overrides
        shown = [d for d in declared if not d.startswith("vehicle.")] + (["vehicle.<key>"] if vehicle else [])
        hint = (f"it is {MEANT_FOR[name]}'s" if name in MEANT_FOR
                else f"did you mean {' or '.join(near)}?" if near else "it overrides only the vehicle values its "
                "config sets" if pre and vehicle else f"it has {', '.join(shown)}")
        raise ValueError(f"parameter {name}: {node} has no such parameter; {hint}")


def node_names_of(argv: Sequence[str]) -> list[str]:
    """The ROS node names a process started with `argv` (discipline_argv, composed_argv) runs."""
    for a in argv:
        if a.startswith("__node:="):
            return [a.split(":=", 1)[1]]
    for a in argv:
        if a.startswith("disciplines:="):
            inst = next((b.split(":=", 1)[1].strip("'") for b in argv if b.startswith("instance:=")), "")
            return [f"{n}_node" + (f"_{inst}" if inst else "") for n in a.split(":=", 1)[1].split(",")]
    return []


def composed_argv(names: Sequence[str], config_path: str, instance: str = "", run_id: str = "") -> list[str]:
    """Command line of one process serving every discipline in `names` (composed.py)."""
    argv = [sys.executable, "-m", "bev_mdo.ros.run", "composed_node", "--ros-args", "-p", f"config:={config_path}",
            "-p", f"disciplines:={','.join(names)}"]  # no __node remap: it would rename every node
    # quoted: a hex instance or run id ("8469814e", "1234") would otherwise be parsed as a number
    if instance:
        argv += ["-p", f"instance:='{instance}'"]
    if run_id:
        argv += ["-p", f"run_id:='{run_id}'"]
    return argv


def parse_instances(spec: str | int | Mapping[str, int] | None, names: Sequence[str],
                    flag: str = "--instances") -> dict[str, int]:
    """``--instances``: ``N`` (every discipline) or ``name=N[,name=N...]`` -> {discipline: instances};
    the API's ``instances=`` may also be an int or a {name: N} mapping (read as the text they write). ``flag``:
    how the errors name what was given (the coordinator node's ``-p instances:=``)."""
    out = dict.fromkeys(names, 1)
    if spec is None:
        return out
    if isinstance(spec, Mapping):
        spec = ",".join(f"{k}={v}" for k, v in spec.items())
    spec = str(spec).strip()
    if not spec:
        raise ValueError(f"{flag} '': give N (every discipline) or NAME=N[,NAME=N...]")
    items = [(None, spec)] if "=" not in spec else [tuple(s.split("=", 1)) for s in spec.split(",") if s.strip()]
    seen: dict[str, str] = {}
    for item in items:
        if len(item) != 2:
            raise ValueError(f"{flag} {spec!r}: give N (every discipline) or NAME=N[,NAME=N...], not both")
        name, count = item
        if name is not None and name.strip() not in out:
            raise ValueError(f"{flag}: no discipline {name.strip()!r} in the config; it has {list(names)}")
        if name is not None and name.strip() in seen:  # the last one used to win silently
            raise ValueError(f"{flag} {name.strip()}: given twice ({seen[name.strip()]} and {count.strip()})")
        if name is not None:
            seen[name.strip()] = count.strip()
        try:
            k = int(count)
        except ValueError:
            raise ValueError(f"{flag}: {count!r} is not a whole number") from None
        if not 1 <= k <= 64:
            raise ValueError(f"{flag}: {k} is outside 1..64")
        for n in ([name.strip()] if name is not None else names):
            out[n] = k
    return out


COMPOSE_COORDINATOR = "coordinator"  # --compose coordinator: every discipline (but pools) in the coordinator's process


def beside_coordinator(compose: str | None, names: Sequence[str], instances: Mapping[str, int] | None = None
                       ) -> list[str]:
    """The disciplines ``--compose coordinator`` runs inside the coordinator's process (every one
    without a pool; a pool's instances keep a process each); empty for any other ``--compose``."""
    if (compose or "none").strip() != COMPOSE_COORDINATOR:
        return []
    return [n for n in names if (instances or {}).get(n, 1) <= 1]


def parse_compose(spec: str | None, names: Sequence[str], pooled: Sequence[str] = ()) -> list[list[str]]:
    """``--compose``: ``none`` (a process per discipline), ``all`` (one process for all), groups
    ``a+b,c+d`` (each group one process; the others alone) or ``coordinator`` (no process: all in the
    coordinator's, see beside_coordinator) -> list of process groups, in order."""
    spec = "none" if spec is None else spec.strip()
    if not spec:  # an empty --compose used to run as none
        raise ValueError("--compose '': give coordinator, none, all or groups A+B,C+D")
    if spec == "none":
        return [[n] for n in names]
    if spec == COMPOSE_COORDINATOR:  # no process: composed into the coordinator's (composed.Beside)
        return []
    if spec == "all":
        return [list(names)]
    groups, seen = [], set()
    for g in spec.split(","):
        members = [m.strip() for m in g.split("+") if m.strip()]
        for m in members:
            if m in pooled:
                raise ValueError(f"--compose: {m!r} runs as a pool (--instances), a process per instance; "
                                 "it cannot be in a group")
            if m not in names:
                raise ValueError(f"--compose: no discipline {m!r} in the config; it has {list(names)}")
            if m in seen:
                raise ValueError(f"--compose: {m!r} is in two groups")
            seen.add(m)
        if members:
            groups.append(members)
    return groups + [[n] for n in names if n not in seen]


def plan_processes(names: Sequence[str], config_path: str, *, run_id: str = "", instance: str = "",
                   instances: Mapping[str, int] | None = None, compose: str | None = None
                   ) -> list[tuple[str, list[str]]]:
    """[(label, argv)] of the discipline processes of a run. A discipline with several instances
    (a pool) runs one process per instance, outside any composed group; the rest as composed."""
    instances = dict(instances or {})
    pooled = [n for n in names if instances.get(n, 1) > 1]
    out: list[tuple[str, list[str]]] = []
    for group in parse_compose(compose, [n for n in names if n not in pooled], pooled):
        if len(group) == 1:
            out.append((group[0], discipline_argv(group[0], config_path, instance=instance, run_id=run_id)))
        else:
            out.append(("+".join(group), composed_argv(group, config_path, instance=instance, run_id=run_id)))
    for n in pooled:
        for k in range(instances[n]):
            out.append((f"{n}#{k}", discipline_argv(n, config_path, instance=f"{instance}_{k}" if instance else str(k),
                                                    run_id=run_id)))
    return out
