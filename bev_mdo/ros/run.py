"""Entry points of the node executables (``ros2 run bev_mdo <exe>``).

``python -m bev_mdo.ros.run <exe> [args]`` does the same; the wrappers in
``<prefix>/lib/bev_mdo/`` call it that way.
"""
from __future__ import annotations

import os
import sys

from bev_mdo.processes import DISCIPLINE_EXES, OTHER_EXES


def run(exe: str, args: list[str] | None = None) -> int:
    """Run one node executable by name. A SIGINT or SIGTERM that lands while it is still loading (imports, config,
    models: before it serves; its run stopped during start-up), or that its main raises on (the coordinator; the
    recorder once its bag is closed), ends it with one line and status 130 (143) (interrupts.run_main)."""
    from bev_mdo import interrupts
    from bev_mdo.stacks import dump_stacks_on_sigusr1
    from bev_mdo.yamlload import read_yaml_file

    dump_stacks_on_sigusr1()

    def load_and_run() -> int:
        main = _load(exe)
        if main is None:
            print(f"unknown executable {exe!r}; known: {', '.join([*DISCIPLINE_EXES, *OTHER_EXES])}", file=sys.stderr)
            return 2
        _config_ros_environment(args or [])
        for path in (b for a, b in zip(args or [], (args or [])[1:]) if a == "--params-file"):
            try:  # one line (not YAML, a key twice, an alias bomb), not rcl's traceback or its last key kept
                read_yaml_file(path)
            except ValueError as exc:
                print(f"{exe}: error: --params-file {exc}", file=sys.stderr)
                return 2
        return main(args)

    return interrupts.run_main(exe, load_and_run)


def _config_ros_environment(args: list[str]) -> None:
    """Started by hand, not by bev-mdo: the domain and discovery that ``-p config:=FILE``'s ``ros:`` states, if any."""
    from bev_mdo.config.load import read_config_file
    from bev_mdo.ros.client import apply_ros_environment
    from bev_mdo.ros_settings import LAUNCHED, choose_domain, validate_ros

    files = [a.split(":=", 1)[1] for a in args if a.startswith("config:=")]
    try:
        stated = {} if os.environ.get(LAUNCHED) or not files else dict(read_config_file(files[-1]).get("ros") or {})
        if "discovery" in stated:
            apply_ros_environment({**validate_ros(stated), "domain_id": choose_domain(stated)[0]})
        elif "domain_id" in stated:
            os.environ["ROS_DOMAIN_ID"] = str(validate_ros(stated)["domain_id"])
    except (ValueError, AttributeError, TypeError):
        pass


def _load(exe: str):
    """The main(args) of executable `exe` (None: no such executable), its modules imported."""
    if exe in DISCIPLINE_EXES or exe in OTHER_EXES:
        # say so at once: importing rclpy, the messages and the models takes a few seconds on a small host
        print(f"{exe}: starting (loading ROS 2 and the models)", file=sys.stderr, flush=True)
    if exe in DISCIPLINE_EXES or exe == "discipline_node":
        from bev_mdo.ros.discipline_node import main

        return lambda args: main(args, discipline=DISCIPLINE_EXES.get(exe))
    if exe == "coordinator_node":
        from bev_mdo.ros.coordinator_node import main
    elif exe == "composed_node":
        from bev_mdo.ros.composed import main
    elif exe == "recorder_node":
        from bev_mdo.ros.recorder_node import main
    else:
        return None
    return main


def _entry(exe: str):
    def main(args: list[str] | None = None) -> int:
        return run(exe, sys.argv[1:] if args is None else args)

    main.__name__ = exe
    return main


for _exe in (*DISCIPLINE_EXES, *OTHER_EXES):
    globals()[_exe] = _entry(_exe)

if __name__ == "__main__":
    if len(sys.argv) < 2:
        print("usage: python -m bev_mdo.ros.run EXECUTABLE [args]", file=sys.stderr)
        sys.exit(2)
    sys.exit(run(sys.argv[1], sys.argv[2:]))
